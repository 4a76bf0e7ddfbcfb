"""The primary threat among several riders (paper Section III-B, step 8).

Criterion (documented, deterministic), over every e-scooter and cyclist of the scenario:

1. **Path conflict.** ``path_distance_m``: the smallest distance from any sample of the
   rider's reconstructed path to the ego's recorded path (the whole path, any time). A rider
   whose path comes within ``corridor_half_width_m`` of the ego path enters the ego's path
   corridor: it is a *conflicting* rider, one a time shift can bring into collision.
2. **Timing at the conflict.** For a conflicting rider, ``pet_s`` (post-encroachment time):
   the smallest ``|t_rider - t_ego|`` over rider samples inside the corridor, where t_ego
   is when the ego passes the nearest point of its path. A small PET means the recording
   already nearly collides.
3. The primary threat is a conflicting rider: **e-scooters before cyclists** (the paper
   studies vehicle / e-scooter interactions; a cyclist is chosen only when no e-scooter
   conflicts), then the smallest PET (ties: smaller ``min_gap_m``). Without conflicting
   riders it is the rider with the smallest ``min_gap_m``, the closest centre-to-centre
   distance to the ego at the same time (riders that never coexist with the ego count as
   infinitely far), e-scooters first among equal gaps; ties break by agent id.
4. A user's choice (``--threat TRACK_ID``: an agent id such as ``escooter_78`` or the
   recording's track id ``78``) overrides the rule: :func:`resolve_threat`.

The figures of every rider (path_distance_m, pet_s, min_gap_m, min_ttc_paper_s = the
paper's TTC D / v_ego while the rider is ahead of the ego inside the corridor) are returned
so that scenario.json can show why one was chosen.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from vei.errors import InputError
from vei.types import RIDER_CATEGORIES, Scenario

FloatArray = npt.NDArray[np.float64]

#: Category order of the rule: e-scooters before cyclists (others last).
CATEGORY_PREFERENCE: tuple[str, ...] = ("escooter", "cyclist")

#: Ego speeds below this [m/s] give no paper TTC (D / v is unbounded).
_TTC_MIN_SPEED_MPS = 0.1


@dataclass(frozen=True)
class ThreatFigures:
    """Why a rider is (or is not) the primary threat.

    Attributes:
        agent_id: the rider.
        path_distance_m: closest approach of the rider's path to the ego's path [m].
        conflict: path_distance_m <= corridor half-width.
        pet_s: post-encroachment time at the conflict [s] (inf if no conflict).
        min_gap_m: closest centre distance to the ego at the same time [m] (inf if never together).
        min_ttc_paper_s: smallest D / v_ego while ahead inside the corridor [s] (inf if never).
        category: 'escooter' or 'cyclist' ('' if unknown: ranked after both).
    """

    agent_id: str
    path_distance_m: float
    conflict: bool
    pet_s: float
    min_gap_m: float
    min_ttc_paper_s: float
    category: str = ""

    def as_dict(self) -> dict:
        """JSON-ready dict (inf -> None)."""

        def f(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {
            "agent_id": self.agent_id,
            "category": self.category,
            "path_distance_m": f(self.path_distance_m),
            "conflict": bool(self.conflict),
            "pet_s": f(self.pet_s),
            "min_gap_m": f(self.min_gap_m),
            "min_ttc_paper_s": f(self.min_ttc_paper_s),
        }


def threat_figures(
    agent_id: str,
    rider_t_s: FloatArray,
    rider_xy_m: FloatArray,
    ego_t_s: FloatArray,
    ego_xy_m: FloatArray,
    ego_yaw_rad: FloatArray,
    ego_speed_mps: FloatArray,
    corridor_half_width_m: float,
    *,
    category: str = "",
) -> ThreatFigures:
    """Figures of one rider against the ego.

    Args:
        agent_id: the rider. category: its category ('escooter', 'cyclist').
        rider_t_s: [N] times on the simulation grid; rider_xy_m: [N, 2] plane positions [m].
        ego_t_s: [M] grid times; ego_xy_m: [M, 2]; ego_yaw_rad: [M]; ego_speed_mps: [M].
        corridor_half_width_m: half-width of the ego's path corridor [m].
    Returns:
        ThreatFigures.
    """
    tree = cKDTree(ego_xy_m)
    dist, idx = tree.query(rider_xy_m)
    path_d = float(dist.min()) if dist.size else np.inf
    inside = dist <= corridor_half_width_m
    conflict = bool(inside.any())
    pet = float(np.min(np.abs(rider_t_s[inside] - ego_t_s[idx[inside]]))) if conflict else np.inf
    # Same-time figures on the common grid (both are on k / rate_hz).
    common, ri, ei = np.intersect1d(
        np.round(rider_t_s, 6), np.round(ego_t_s, 6), return_indices=True
    )
    if common.size:
        rel = rider_xy_m[ri] - ego_xy_m[ei]
        gap = np.hypot(rel[:, 0], rel[:, 1])
        min_gap = float(gap.min())
        yaw = ego_yaw_rad[ei]
        fwd = rel[:, 0] * np.cos(yaw) + rel[:, 1] * np.sin(yaw)
        lat = -rel[:, 0] * np.sin(yaw) + rel[:, 1] * np.cos(yaw)
        v = ego_speed_mps[ei]
        ahead = (fwd > 0) & (np.abs(lat) <= corridor_half_width_m) & (v > _TTC_MIN_SPEED_MPS)
        min_ttc = float(np.min(gap[ahead] / v[ahead])) if ahead.any() else np.inf
    else:
        min_gap, min_ttc = np.inf, np.inf
    return ThreatFigures(agent_id, path_d, conflict, pet, min_gap, min_ttc, category)


def _rank(category: str) -> int:
    return (
        CATEGORY_PREFERENCE.index(category)
        if category in CATEGORY_PREFERENCE
        else len(CATEGORY_PREFERENCE)
    )


def primary_threat(figures: list[ThreatFigures]) -> str | None:
    """Agent id of the primary threat by the module's criterion (None if no riders)."""
    if not figures:
        return None
    conflicting = [f for f in figures if f.conflict]
    if conflicting:
        best = min(conflicting, key=lambda f: (_rank(f.category), f.pet_s, f.min_gap_m, f.agent_id))
    else:
        best = min(
            figures,
            key=lambda f: (f.min_gap_m, _rank(f.category), f.path_distance_m, f.agent_id),
        )
    return best.agent_id


def resolve_threat(value: str, riders: dict[str, tuple[str, str | None]], where: str) -> str:
    """The agent id a user's ``--threat`` names.

    Args:
        value: an agent id ('escooter_78') or the recording's track id ('78').
        riders: {agent_id: (category, source_track_id)} of the scenario's riders.
        where: the scenario (for the message).
    Returns:
        The rider's agent id; InputError (listing the riders) if none or several match.
    """
    text = str(value).strip()
    if text in riders:
        return text
    hits = [a for a, (_, src) in riders.items() if src is not None and str(src) == text]
    if len(hits) == 1:
        return hits[0]
    listing = ", ".join(
        f"{a} (track {src})" if src is not None else a for a, (_, src) in sorted(riders.items())
    )
    why = "matches several riders" if hits else "is not a rider of this scenario"
    raise InputError(
        f"--threat {text!r} {why}; riders (e-scooters and cyclists): {listing or 'none'}",
        path=where,
        field="threat",
    )


def with_threat(scenario: Scenario, value: str | None) -> Scenario:
    """The scenario with ``value`` (agent id or track id, see :func:`resolve_threat`) as its
    primary threat; unchanged when value is None. Records the choice in
    ``extra['threat']['chosen_by']`` ('user')."""
    if value is None:
        return scenario
    riders = {
        a.agent_id: (a.category, a.source_track_id)
        for a in scenario.agents
        if a.category in RIDER_CATEGORIES
    }
    aid = resolve_threat(value, riders, str(scenario.root or f"scenario {scenario.id}"))
    extra = dict(scenario.extra)
    threat = dict(extra.get("threat", {}))
    threat.update({"chosen_by": "user", "rule_choice": scenario.primary_threat})
    extra["threat"] = threat
    return dataclasses.replace(scenario, primary_threat=aid, extra=extra)
