"""Every tracker family, by name: the registry the machinery asks (sweeps, tunes, a stored config's
result files), so that it names the protocol (:class:`dfrmot_jax.family.TrackerFamily`) and never
one family's modules.

``FAMILIES``: name -> family; :func:`family_of` looks one up. DFR-FastMOT (``"dfr"``,
:data:`dfrmot_jax.dfr.FAMILY`) is the first, AB3DMOT (``"ab3dmot"``,
:data:`dfrmot_jax.ab3dmot.family.FAMILY`) the second. A family joins by one more entry in each registry: its
:class:`~dfrmot_jax.family.TrackerFamily` here and its ``FamilyConfig`` in
:data:`dfrmot_jax.family_configs.CONFIGS`, from a module of its own that reaches no JAX (as DFR's
``config.FAMILY_CONFIG``), so that the report and ``--help`` read its settings without the tracker;
or, at run time, through :func:`register`, which records both (a Ray worker, a process of its own,
knows only the families registered when the package is imported).
"""

from __future__ import annotations

from . import dfr
from .ab3dmot import family as ab3dmot
from .family import DEFAULT_FAMILY, TrackerFamily, family_problems
from .family_configs import CONFIGS, family_config, family_names

__all__ = ["FAMILIES", "DEFAULT_FAMILY", "family_of", "register", "unregister", "family_names"]

#: family name -> family (:func:`register` adds one)
FAMILIES: dict[str, TrackerFamily] = {f.name: f for f in (dfr.FAMILY, ab3dmot.FAMILY)}


def family_of(name: str = DEFAULT_FAMILY) -> TrackerFamily:
    """The family ``name`` (ValueError naming the registered ones when there is none)."""
    family_config(name)                   # (the one message for an unknown name)
    return FAMILIES[name]


def register(family: TrackerFamily, *, replace: bool = False) -> TrackerFamily:
    """Add ``family`` to the registry (its config to :mod:`dfrmot_jax.family_configs`'). ValueError
    when it breaks the protocol (:func:`dfrmot_jax.family.family_problems`) or its name is taken
    (unless ``replace``; the default family is never replaced)."""
    problems = family_problems(family)
    if problems:
        raise ValueError(f"family {family.name!r} does not follow the protocol: {'; '.join(problems)}")
    if family.name == DEFAULT_FAMILY or family.name in FAMILIES and not replace:
        raise ValueError(f"family {family.name!r} is registered already")
    FAMILIES[family.name] = family
    CONFIGS[family.name] = family.config
    return family


def unregister(name: str) -> None:
    """Remove family ``name`` (not the default one) from both registries; nothing when it is not there."""
    if name == DEFAULT_FAMILY:
        raise ValueError(f"the default family {name!r} stays registered")
    FAMILIES.pop(name, None)
    CONFIGS.pop(name, None)
