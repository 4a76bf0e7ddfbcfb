"""Sweep / population column names of a rider population (no heavy imports: every sweep
worker imports them; :mod:`vei.calibrate.population` re-exports them)."""

from __future__ import annotations

#: VariantParams fields a population sets (k_des_nspm before the case's k_des factor).
POPULATION_FIELDS: tuple[str, ...] = (
    "v0_mps",
    "k_des_nspm",
    "mass_kg",
    "sigma_m",
    "lookahead_m",
    "max_speed_mps",
    "max_accel_mps2",
    "a_veh_n",
    "b_veh_per_m",
)
#: Sweep variants-table column of the population rider a variant runs with (0..N-1).
RIDER_COLUMN = "rider_sample"
#: Sweep variants-table columns of a population rider's parameters -> VariantParams field
#: (rider.k_des_nspm before the configuration's k_des_factor).
RIDER_PARAM_COLUMNS: dict[str, str] = {f"rider.{f}": f for f in POPULATION_FIELDS}
#: Sweep parameters a rider population sets (not sweepable together with it).
POPULATION_SET: tuple[str, ...] = (
    "sfm.k_des_nspm",
    "sfm.a_veh_n",
    "sfm.b_veh_per_m",
    "sfm.v0_mps",
    "sfm.mass_kg",
)
