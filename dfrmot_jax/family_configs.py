"""Every family's settings, without its tracker: the registry a sweep file's validation, a stored
table's columns and ``--help`` read (NumPy only: nothing here reaches JAX).

``CONFIGS``: family name -> its :class:`~dfrmot_jax.family.FamilyConfig`; :func:`family_config`
looks one up. DFR-FastMOT (``"dfr"``) and AB3DMOT (``"ab3dmot"``) are registered. A family
joins by one more entry here (its config, from a module of its own that
reaches no JAX, as DFR-FastMOT's ``config.FAMILY_CONFIG``) and its tracker in
:data:`dfrmot_jax.families.FAMILIES`, or at run time through :func:`dfrmot_jax.families.register`,
which records both.
"""

from __future__ import annotations

from . import config
from .ab3dmot import config as ab3dmot_config
from .family import DEFAULT_FAMILY, FamilyConfig

__all__ = ["CONFIGS", "family_config", "family_names", "preset_family", "all_presets"]

#: family name -> its settings (``families.register`` adds one)
CONFIGS: dict[str, FamilyConfig] = {fc.name: fc for fc in (config.FAMILY_CONFIG, ab3dmot_config.FAMILY_CONFIG)}


def family_names() -> tuple[str, ...]:
    """The registered families' names, the default first."""
    return tuple(sorted(CONFIGS, key=lambda n: (n != DEFAULT_FAMILY, n)))


def family_config(name: str = DEFAULT_FAMILY) -> FamilyConfig:
    """The settings of family ``name`` (ValueError naming the registered ones when there is none)."""
    try:
        return CONFIGS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown tracker family {name!r}: expected one of {list(family_names())}") from None


def all_presets() -> tuple[str, ...]:
    """Every registered family's presets, the default family's first."""
    return tuple(name for f in family_names() for name in CONFIGS[f].presets)


def preset_family(preset: str) -> FamilyConfig:
    """The settings of the family a preset belongs to (ValueError naming every preset when none has it)."""
    for f in family_names():
        if preset in CONFIGS[f].presets:
            return CONFIGS[f]
    raise ValueError(f"unknown preset {preset!r}: expected one of {list(all_presets())}")
