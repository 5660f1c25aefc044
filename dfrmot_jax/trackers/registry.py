"""Every tracker family, by name: the registry the machinery asks (sweeps, tunes, a stored config's
result files, the report, ``--help``), so that it names the protocol (:mod:`dfrmot_jax.trackers.protocol`)
and never one family's modules.

A family joins by one line here: its ``FamilyConfig`` (from the ``config`` module of its folder,
which reaches no JAX) in the tuple of :data:`CONFIGS`. Its tracker (the ``TrackerFamily``,
``FAMILY`` in the module its config names as ``tracker``) is imported when first asked for
(:func:`family_of`, :data:`FAMILIES`), so that reading settings (a sweep file's validation, a stored
table's columns, ``--help``, the report) never imports JAX. At run time :func:`register` adds a
family built elsewhere (a Ray worker, a process of its own, knows only the families registered when
the package is imported).
"""

from __future__ import annotations

import importlib

from .ab3dmot import config as ab3dmot
from .bytetrack import config as bytetrack
from .dfr import config as dfr
from .protocol import DEFAULT_FAMILY, FamilyConfig, TrackerFamily, family_problems

__all__ = ["CONFIGS", "FAMILIES", "DEFAULT_FAMILY", "all_presets", "family_config", "family_names", "family_of", "load_family",
           "preset_family", "register", "unregister"]

#: family name -> its settings (:func:`register` adds one)
CONFIGS: dict[str, FamilyConfig] = {fc.name: fc for fc in (dfr.FAMILY_CONFIG, ab3dmot.FAMILY_CONFIG, bytetrack.FAMILY_CONFIG)}


def load_family(name: str) -> TrackerFamily:
    """The ``TrackerFamily`` of registered family ``name``: ``FAMILY`` of the module its config names
    (``FamilyConfig.tracker``), imported now (KeyError when there is none)."""
    fc = CONFIGS.get(name)
    if fc is None or not fc.tracker:
        raise KeyError(name)
    return importlib.import_module(fc.tracker).FAMILY


class _Families(dict):
    """family name -> its ``TrackerFamily``, imported from the module its config names (``tracker``)
    when first asked for (:func:`load_family`)."""

    def __missing__(self, name: str) -> TrackerFamily:
        family = self[name] = load_family(name)
        return family

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or (name in CONFIGS and bool(CONFIGS[name].tracker))


#: family name -> family (each imported on first use; :func:`register` adds one)
FAMILIES: dict[str, TrackerFamily] = _Families()


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


def family_of(name: str = DEFAULT_FAMILY) -> TrackerFamily:
    """The family ``name`` (ValueError naming the registered ones when there is none)."""
    family_config(name)                   # (the one message for an unknown name)
    return FAMILIES[name]


def register(family: TrackerFamily, *, replace: bool = False) -> TrackerFamily:
    """Add ``family`` to the registry (its tracker and its config). ValueError when it breaks the
    protocol (:func:`dfrmot_jax.trackers.protocol.family_problems`) or its name is taken (unless
    ``replace``; the default family is never replaced)."""
    problems = family_problems(family)
    if problems:
        raise ValueError(f"family {family.name!r} does not follow the protocol: {'; '.join(problems)}")
    if family.name == DEFAULT_FAMILY or family.name in CONFIGS and not replace:
        raise ValueError(f"family {family.name!r} is registered already")
    FAMILIES[family.name] = family
    CONFIGS[family.name] = family.config
    return family


def unregister(name: str) -> None:
    """Remove family ``name`` (not the default one) from the registry; nothing when it is not there."""
    if name == DEFAULT_FAMILY:
        raise ValueError(f"the default family {name!r} stays registered")
    FAMILIES.pop(name, None)
    CONFIGS.pop(name, None)
