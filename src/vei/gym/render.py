"""A bird's-eye picture of one environment's current step (render_mode 'rgb_array').

The scenario's road network (vei.maps, from its own map.xodr) under the boxes of the ego
(blue), the primary rider (red) and the replayed road users present (grey), 60 m wide
around the ego, x east / y north [m]; a scenario without a map says so in the title.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import box_corners


def render_state(ws: Any, st: Any, b: int, half_width_m: float = 30.0) -> npt.NDArray[np.uint8]:
    """[H, W, 3] uint8 picture of environment ``b`` of the SimState ``st`` in scenario ``ws``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    from vei.report.birdseye import scenario_roads

    arrays = ws.arrays
    fig = Figure(figsize=(5, 5), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    roads = scenario_roads(ws.scenario)
    if roads is not None:
        roads(ax)

    def box(x: float, y: float, yaw: float, length: float, width: float, colour: str) -> None:
        c = box_corners(np.array([x]), np.array([y]), np.array([yaw]), length, width)[0]
        ax.add_patch(Polygon(c, closed=True, facecolor=colour, edgecolor="black", lw=0.5))

    k = int(st.k)
    for j in np.flatnonzero(arrays.other_active[k]):
        box(arrays.other_x_m[k, j], arrays.other_y_m[k, j], arrays.other_yaw_rad[k, j],
            arrays.other_length_m[j], arrays.other_width_m[j], "#999999")  # fmt: skip
    if st.rider_active[b]:
        box(st.rider_x_m[b], st.rider_y_m[b], st.rider_yaw_rad[b], arrays.rider_length_m,
            arrays.rider_width_m, "tab:red")  # fmt: skip
    ex, ey = float(st.ego_x_m[b]), float(st.ego_y_m[b])
    box(ex, ey, st.ego_yaw_rad[b], arrays.ego_length_m, arrays.ego_width_m, "tab:blue")
    ax.set_xlim(ex - half_width_m, ex + half_width_m)
    ax.set_ylim(ey - half_width_m, ey + half_width_m)
    ax.set_aspect("equal")
    note = "" if roads is not None else " (no road map)"
    ax.set_title(f"{ws.name} t = {k * arrays.dt_s:.2f} s{note}", fontsize=8)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()


__all__ = ["render_state"]
