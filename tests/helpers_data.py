"""Names of the shared real recordings the tests use (the data lives in ../shared/data)."""

from __future__ import annotations

#: The trafficmonitoring recordings with a rider (the other two, marktkauf_04 and
#: marktkauf_05, have none: the importer refuses them).
REAL_WITH_RIDER = (
    "audi_08_klinikum_rechtsabbiegen",
    "audi_08_klinikum_rechtsabbiegen_02",
    "audi_08_stadtmitte_geradeaus",
    "audi_10_marktkauf_linksabbiegen",
    "klinikum_01_marktkauf_geradeaus",
    "stadtmitte_11_marktkauf_rechtsabbiegen_02",
    "stadtmitte_12_audi_geradeaus_03",
)
