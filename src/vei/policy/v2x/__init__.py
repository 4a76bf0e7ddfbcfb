"""V2X: riders that announce themselves (VRU awareness messages), a radio channel, and a
car that fuses what it receives with its own perception.

- :mod:`.vam`: the rider side (ETSI TS 103 300-3 generation rules, GNSS error);
- :mod:`.channel`: 3GPP TR 37.885 path loss per link state (LOS, NLOSv, NLOS), the link
  budget of each technology, delivery, latency;
- :mod:`.links`: which links are blocked, by vehicle boxes (with their heights) or by the
  map's buildings;
- :mod:`.model`: one batched, seeded step from the riders' truth to the car's V2X tracks;
- :mod:`.fusion`: the tracks fused with the on-board perception (source and age per road
  user of the policy's Observation);
- :mod:`.report`: what V2X did in a run (messages, first track, known from V2X alone,
  braked on it).

The configuration is :class:`vei.config.v2x.V2XConfig` (``case: {v2x: {...}}``); the
engine runs it in :class:`vei.sim.observe.PolicyDriver`. docs/v2x.md describes the model
and the source of every default.
"""

from vei.config.v2x import V2XConfig

__all__ = ["V2XConfig"]
