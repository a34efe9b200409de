"""Moved: :class:`hybridnav.tuner.settings.TunableSettings` replaces ``GenomeSpace``. This alias
keeps ``GenomeSpace(template, free)`` (a job's ``[free]`` table) working for one version."""

from __future__ import annotations

from typing import Any

from hybridnav.tuner.settings import Gene, TunableSettings

__all__ = ["Gene", "GenomeSpace"]


class GenomeSpace(TunableSettings):
    """``TunableSettings.from_table(template, free)`` under its old name and method names."""

    def __init__(self, template, free: dict[str, Any]) -> None:
        s = TunableSettings.from_table(template, {"margin": 0.0, **free})
        self.__dict__.update(s.__dict__)

    def encode(self, system=None):
        """Old name of :meth:`TunableSettings.to_vector`."""
        return self.to_vector(system)

    def system(self, x, name=None, description=None):
        """Old name of :meth:`TunableSettings.to_system`."""
        return self.to_system(x, name, description)
