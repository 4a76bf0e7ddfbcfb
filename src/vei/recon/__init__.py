"""vei.recon: interaction -> world-frame scenario (paper Section III-B).

Modules: ``sync`` (time sync, active agents), ``world`` (ego pose, ego-relative -> world),
``keyframes`` (sparse keyframes per track), ``interpolate`` (cubic / linear / smoothing
spline positions, SLERP yaw), ``threat`` (primary threat), ``pipeline``
(:class:`~vei.recon.pipeline.ReconstructionConfig`, :func:`~vei.recon.pipeline.reconstruct`).
"""
