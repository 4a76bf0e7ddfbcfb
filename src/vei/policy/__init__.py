"""Ego policies: the batched interface between the world and the ego's longitudinal decision.

See docs/policy.md. Modules: observation (what a policy sees), base (the interface and the
per-variant adapter), builtin (none = PID cruise, paper-cap), aeb, idm, load (specs).
"""
