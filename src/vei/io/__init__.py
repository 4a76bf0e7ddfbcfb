"""Readers and writers: the interaction format, scenario folders, atomic outputs."""

from vei.io.interaction import read_interaction, write_interaction

__all__ = ["read_interaction", "write_interaction"]
