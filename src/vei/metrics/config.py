"""Configuration of the safety metrics: :class:`MetricsConfig` lives at the config layer
(:mod:`vei.config.metrics`, so that ``RunConfig.metrics`` can hold it) and is re-exported
here."""

from __future__ import annotations

from vei.config.metrics import PAPER_METRICS, MetricsConfig, TtcScope

__all__ = ["PAPER_METRICS", "MetricsConfig", "TtcScope"]
