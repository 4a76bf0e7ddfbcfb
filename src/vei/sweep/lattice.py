"""Critical-boundary lattice: where, in a plane of two parameters, collisions begin.

Algorithm (adaptive quadtree refinement, "marching squares with bisection"):

1. Lay a lattice over the box ``[x_min, x_max] x [y_min, y_max]`` with ``(nx - 1) * 2**L + 1``
   by ``(ny - 1) * 2**L + 1`` points (the resolution of a full grid with ``L`` refinement
   levels). Evaluate the ``nx x ny`` coarse points (lattice stride ``2**L``) in one batch.
2. A cell whose four corners disagree (some collide, some do not) contains the boundary.
   Split every such cell into four (stride halves): its five new points (edge midpoints and
   centre) are evaluated, all cells of one level in one engine batch, each lattice point
   at most once. Cells whose corners agree are not refined.
3. After ``L`` levels every mixed cell has the finest stride. On each of its edges whose
   end points disagree the boundary crosses; the crossing lies at the edge midpoint (or,
   given a continuous score with a threshold, at the linearly interpolated level). The
   crossings of one cell are joined into a segment (marching squares); a saddle cell
   (diagonal corners equal) gives two segments.

Cost: about ``nx * ny + 5 * (cells on the boundary) * L`` evaluations instead of the
``((nx-1) 2**L + 1) * ((ny-1) 2**L + 1)`` of the full grid of the same resolution, i.e.
linear instead of quadratic in the resolution for a boundary curve. Limitation (stated,
not hidden): features smaller than a coarse cell whose corners all agree (an island of
collisions, or a boundary crossing one edge twice) are not found; choose ``nx, ny`` so
that a coarse cell is smaller than the smallest feature expected.

:func:`adaptive_boundary` runs it against any vectorised oracle (a test recovers a known
line with it); :func:`vei.experiments.boundary.search_boundary` against the simulation
(the two axes are sweep parameters, everything else fixed by a sweep spec). The lattice
helpers below (:func:`binned_risk`, :func:`share_boundary`, :func:`lattice_segments`)
also draw the boundary of a sweep's risk map (:mod:`vei.sweep.riskmap`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import ConfigError

#: Oracle: points [N, 2] (x, y) -> {'collision': bool [N], other metric columns [N] ...}.
Oracle = Callable[[np.ndarray], Mapping[str, Any]]


@dataclass(frozen=True)
class BoundaryResult:
    """Outcome of a boundary search.

    Attributes:
        x_name, y_name: parameter names of the axes.
        x_values: [Mx] finest lattice coordinates along x; y_values: [My] along y.
        samples: one row per evaluated point: columns x, y, i, j (lattice indices), level
            (refinement level at which it was evaluated, 0 = coarse), collision (bool) and
            every other column the oracle returned.
        segments: [S, 2, 2] boundary segments ((x0, y0), (x1, y1)) in parameter units.
        crossings: [P, 2] boundary crossing points on lattice edges (each between a
            colliding and a non-colliding lattice neighbour).
        n_evaluations: number of points evaluated (= len(samples)).
        grid_evaluations: evaluations a full grid of the same resolution needs (Mx * My).
    """

    x_name: str
    y_name: str
    x_values: np.ndarray
    y_values: np.ndarray
    samples: pd.DataFrame
    segments: np.ndarray
    crossings: np.ndarray
    n_evaluations: int
    grid_evaluations: int


def lattice_segments(
    label: np.ndarray,
    x_values: np.ndarray,
    y_values: np.ndarray,
    cells: np.ndarray | None = None,
    *,
    score: np.ndarray | None = None,
    threshold: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Boundary segments between label 1 and label 0 on a rectilinear lattice (marching squares).

    Args:
        label: [My, Mx] int, 1 = collision, 0 = none, -1 = not evaluated.
        x_values: [Mx] lattice x coordinates; y_values: [My] lattice y coordinates.
        cells: [C, 2] (i, j) lower-left corners of unit cells to examine; default: every cell.
        score: optional [My, Mx] float with ``label == (score >= threshold)``; crossings are
            then placed by linear interpolation of the score instead of at edge midpoints.
        threshold: level of ``score`` that is the boundary.

    Returns:
        (segments [S, 2, 2], crossings [P, 2]) in x/y units; P counts each lattice edge once.
        Cells with an unevaluated corner are skipped.
    """
    my, mx = label.shape
    if cells is None:
        jj, ii = np.meshgrid(np.arange(my - 1), np.arange(mx - 1), indexing="ij")
        cells = np.column_stack([ii.ravel(), jj.ravel()])
    segments: list[tuple[tuple[float, float], tuple[float, float]]] = []
    crossing_map: dict[tuple[int, int, int, int], tuple[float, float]] = {}

    def cross(a: tuple[int, int], b: tuple[int, int]) -> tuple[float, float]:
        key = (*a, *b) if a <= b else (*b, *a)
        if key in crossing_map:
            return crossing_map[key]
        (ia, ja), (ib, jb) = a, b
        t = 0.5
        if score is not None:
            sa, sb = float(score[ja, ia]), float(score[jb, ib])
            if np.isfinite(sa) and np.isfinite(sb) and sa != sb:
                t = float(np.clip((threshold - sa) / (sb - sa), 0.0, 1.0))
        p = (
            float(x_values[ia] + t * (x_values[ib] - x_values[ia])),
            float(y_values[ja] + t * (y_values[jb] - y_values[ja])),
        )
        crossing_map[key] = p
        return p

    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    # only cells with two labels and none unevaluated cross the boundary (vectorised filter,
    # same cells in the same order: a 1000 x 1000 sweep grid has ~10^3 of its 10^6 cells)
    ci, cj = cells[:, 0], cells[:, 1]
    quad = np.stack(
        [label[cj, ci], label[cj, ci + 1], label[cj + 1, ci + 1], label[cj + 1, ci]], axis=1
    )
    mixed = (quad.min(axis=1) >= 0) & (quad.min(axis=1) != quad.max(axis=1))
    for i, j in cells[mixed]:
        corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]  # counter-clockwise
        lab = [int(label[c[1], c[0]]) for c in corners]
        if min(lab) < 0 or len(set(lab)) == 1:
            continue
        # edges in order: bottom, right, top, left
        pts = [
            cross(corners[k], corners[(k + 1) % 4]) for k in range(4) if lab[k] != lab[(k + 1) % 4]
        ]
        if len(pts) == 2:
            segments.append((pts[0], pts[1]))
        elif len(pts) == 4:  # saddle: keep the colliding corners apart (pair around corner 0/2)
            if lab[0] == 1:
                segments.append((pts[3], pts[0]))
                segments.append((pts[1], pts[2]))
            else:
                segments.append((pts[0], pts[1]))
                segments.append((pts[2], pts[3]))
    seg = np.array(segments, dtype=np.float64).reshape(-1, 2, 2)
    crs = np.array(list(crossing_map.values()), dtype=np.float64).reshape(-1, 2)
    return seg, crs


def adaptive_boundary(
    oracle: Oracle,
    x_range: tuple[float, float],
    y_range: tuple[float, float],
    *,
    coarse: tuple[int, int] = (9, 9),
    levels: int = 4,
    x_name: str = "x",
    y_name: str = "y",
    progress: Callable[[int, int], None] | None = None,
) -> BoundaryResult:
    """Find the collision boundary in a box by adaptive quadtree refinement (module docstring).

    Args:
        oracle: vectorised evaluation, points [N, 2] -> mapping with 'collision' [N] bool
            and any other per-point columns [N] (kept in ``samples``).
        x_range, y_range: (min, max) of the box, min < max.
        coarse: (nx, ny) >= 2 coarse grid points per axis.
        levels: refinement levels L >= 0 (finest stride = coarse stride / 2**L).
        x_name, y_name: axis names stored in the result.
        progress: optional callback(level, points evaluated so far).

    Returns:
        a :class:`BoundaryResult`.
    """
    nx, ny = (int(c) for c in coarse)
    if nx < 2 or ny < 2:
        raise ConfigError(f"coarse grid needs >= 2 points per axis, got {coarse}")
    if levels < 0:
        raise ConfigError(f"levels must be >= 0, got {levels}")
    if not (x_range[0] < x_range[1] and y_range[0] < y_range[1]):
        raise ConfigError(f"boundary box needs min < max, got x {x_range}, y {y_range}")
    stride = 2**levels
    mx, my = (nx - 1) * stride + 1, (ny - 1) * stride + 1
    xv = np.linspace(x_range[0], x_range[1], mx)
    yv = np.linspace(y_range[0], y_range[1], my)
    label = np.full((my, mx), -1, dtype=np.int8)
    records: list[pd.DataFrame] = []

    def evaluate(ij: np.ndarray, level: int) -> None:
        ij = np.unique(ij.reshape(-1, 2), axis=0)
        ij = ij[label[ij[:, 1], ij[:, 0]] < 0]
        if len(ij) == 0:
            return
        pts = np.column_stack([xv[ij[:, 0]], yv[ij[:, 1]]])
        out = dict(oracle(pts))
        if "collision" not in out:
            raise ConfigError("boundary oracle must return a 'collision' column")
        col = np.asarray(out.pop("collision"), dtype=bool).reshape(-1)
        if col.shape[0] != len(ij):
            raise ConfigError(
                f"boundary oracle returned {col.shape[0]} values for {len(ij)} points"
            )
        label[ij[:, 1], ij[:, 0]] = col.astype(np.int8)
        frame = pd.DataFrame(
            {
                "x": pts[:, 0],
                "y": pts[:, 1],
                "i": ij[:, 0],
                "j": ij[:, 1],
                "level": level,
                "collision": col,
            }
        )
        for k, v in out.items():
            frame[k] = np.asarray(v).reshape(-1) if np.ndim(v) else v
        records.append(frame)
        if progress is not None:
            progress(level, int(sum(len(r) for r in records)))

    ci, cj = np.meshgrid(np.arange(0, mx, stride), np.arange(0, my, stride), indexing="xy")
    evaluate(np.column_stack([ci.ravel(), cj.ravel()]), 0)
    cells = np.column_stack(
        [
            np.meshgrid(np.arange(0, mx - 1, stride), np.arange(0, my - 1, stride), indexing="xy")[
                0
            ].ravel(),
            np.meshgrid(np.arange(0, mx - 1, stride), np.arange(0, my - 1, stride), indexing="xy")[
                1
            ].ravel(),
        ]
    )
    s = stride
    for level in range(1, levels + 1):
        mixed = _mixed(label, cells, s)
        h = s // 2
        if len(mixed) == 0:
            break
        i0, j0 = mixed[:, 0], mixed[:, 1]
        new = np.concatenate(
            [
                np.column_stack([i0 + h, j0]),
                np.column_stack([i0, j0 + h]),
                np.column_stack([i0 + h, j0 + h]),
                np.column_stack([i0 + s, j0 + h]),
                np.column_stack([i0 + h, j0 + s]),
            ]
        )
        evaluate(new, level)
        cells = np.concatenate(
            [
                np.column_stack([i0, j0]),
                np.column_stack([i0 + h, j0]),
                np.column_stack([i0, j0 + h]),
                np.column_stack([i0 + h, j0 + h]),
            ]
        )
        s = h
    final = _mixed(label, cells, s) if s == 1 else np.zeros((0, 2), dtype=np.int64)
    segments, crossings = lattice_segments(label, xv, yv, final)
    samples = pd.concat(records, ignore_index=True)
    return BoundaryResult(
        x_name=x_name,
        y_name=y_name,
        x_values=xv,
        y_values=yv,
        samples=samples,
        segments=segments,
        crossings=crossings,
        n_evaluations=len(samples),
        grid_evaluations=mx * my,
    )


def _mixed(label: np.ndarray, cells: np.ndarray, s: int) -> np.ndarray:
    """Cells (lower-left corner, stride s) whose four corners have different labels."""
    if len(cells) == 0:
        return cells.reshape(0, 2)
    i0, j0 = cells[:, 0], cells[:, 1]
    c = np.stack(
        [label[j0, i0], label[j0, i0 + s], label[j0 + s, i0 + s], label[j0 + s, i0]], axis=1
    )
    return cells[(c.min(axis=1) != c.max(axis=1))]


def binned_risk(
    x: np.ndarray,
    y: np.ndarray,
    collided: np.ndarray,
    value: np.ndarray,
    x_edges: np.ndarray,
    y_edges: np.ndarray,
) -> dict[str, np.ndarray]:
    """Bin scattered variants of a plane: mean value and collision share per bin.

    Args:
        x, y: [N] parameter values; collided: [N] bool; value: [N] (e.g. safety index).
        x_edges: [Kx + 1], y_edges: [Ky + 1] increasing bin edges.

    Returns:
        {'value': [Ky, Kx] mean value (NaN in empty bins), 'collision_share': [Ky, Kx] in
        [0, 1] (NaN empty), 'count': [Ky, Kx] int, 'x_centres': [Kx], 'y_centres': [Ky]}.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    kx, ky = len(x_edges) - 1, len(y_edges) - 1
    bi = np.clip(np.searchsorted(x_edges, x, side="right") - 1, 0, kx - 1)
    bj = np.clip(np.searchsorted(y_edges, y, side="right") - 1, 0, ky - 1)
    flat = bj * kx + bi
    count = np.bincount(flat, minlength=kx * ky).reshape(ky, kx)
    vsum = np.bincount(flat, weights=np.asarray(value, float), minlength=kx * ky).reshape(ky, kx)
    csum = np.bincount(flat, weights=np.asarray(collided, float), minlength=kx * ky).reshape(ky, kx)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, vsum / np.maximum(count, 1), np.nan)
        share = np.where(count > 0, csum / np.maximum(count, 1), np.nan)
    return {
        "value": mean,
        "collision_share": share,
        "count": count,
        "x_centres": 0.5 * (x_edges[:-1] + x_edges[1:]),
        "y_centres": 0.5 * (y_edges[:-1] + y_edges[1:]),
    }


def share_boundary(binned: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Boundary (collision share = 0.5) of :func:`binned_risk` output, by marching squares.

    Returns (segments [S, 2, 2], crossings [P, 2]) in parameter units; empty bins are skipped.
    """
    share = np.asarray(binned["collision_share"], float)
    label = np.where(np.isfinite(share), (share >= 0.5).astype(np.int8), -1).astype(np.int8)
    return lattice_segments(
        label, binned["x_centres"], binned["y_centres"], score=share, threshold=0.5
    )


def lattice_heatmap(
    result: BoundaryResult, column: str = "safety_index", max_cells: int = 257
) -> dict[str, np.ndarray]:
    """A value field of the search on a regular lattice, for the risk map.

    Linear interpolation (Delaunay) of ``samples[column]`` over the lattice of the search
    (subsampled to at most ``max_cells`` per axis), nearest sample where linear is undefined.

    Returns:
        {'x_centres': [Kx], 'y_centres': [Ky], 'value': [Ky, Kx]}.
    """
    from scipy.interpolate import griddata

    s = result.samples
    pts = s[["x", "y"]].to_numpy(float)
    vals = s[column].to_numpy(float)
    xs = result.x_values[:: max(1, int(np.ceil(len(result.x_values) / max_cells)))]
    ys = result.y_values[:: max(1, int(np.ceil(len(result.y_values) / max_cells)))]
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    ok = np.isfinite(vals)
    lin = griddata(pts[ok], vals[ok], (gx, gy), method="linear")
    near = griddata(pts[ok], vals[ok], (gx, gy), method="nearest")
    return {"x_centres": xs, "y_centres": ys, "value": np.where(np.isfinite(lin), lin, near)}


def boundary_neighbours(result: BoundaryResult) -> pd.DataFrame:
    """Samples at either end of a lattice edge that the boundary crosses (finest level):
    each pair is a colliding variant and a non-colliding one one lattice step apart."""
    s = result.samples
    key = {(int(i), int(j)): n for n, (i, j) in enumerate(zip(s["i"], s["j"], strict=True))}
    col = s["collision"].to_numpy(bool)
    keep = np.zeros(len(s), dtype=bool)
    for n, (i, j) in enumerate(zip(s["i"], s["j"], strict=True)):
        for di, dj in ((1, 0), (0, 1)):
            m = key.get((int(i) + di, int(j) + dj))
            if m is not None and col[m] != col[n]:
                keep[n] = keep[m] = True
    return s[keep].reset_index(drop=True)
