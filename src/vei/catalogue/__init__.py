"""Risk catalogue over a whole dataset: find every car-rider encounter, make it critical,
sweep it, score and rank it (``vei catalogue``; docs/catalogue.md)."""

from vei.catalogue.config import CatalogueConfig, load_catalogue_config
from vei.catalogue.encounters import Encounter, EncounterRule, find_encounters
from vei.catalogue.run import CatalogueResult, run_catalogue

__all__ = [
    "CatalogueConfig",
    "CatalogueResult",
    "Encounter",
    "EncounterRule",
    "find_encounters",
    "load_catalogue_config",
    "run_catalogue",
]
