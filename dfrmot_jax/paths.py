"""Where the KITTI data lives, and where ``dfrmot`` keeps compiled programs by default.

The data are never part of the repository. ``DFRMOT_DATA`` names the KITTI tracking *training*
root (the folder that holds ``label_02/``, ``calib/`` and ``detections/``); without it we look for
``../shared/data/kitti/training`` relative to the current directory (run from a checkout's root),
then beside the package's own checkout (an editable install run from elsewhere).
"""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "DFRMOT_DATA"
#: the compile cache folder's variable (read by ``devices.setup_compile_cache``, which names it too)
COMPILE_CACHE_VAR = "DFRMOT_COMPILE_CACHE"
RELATIVE = Path("..") / "shared" / "data" / "kitti" / "training"
_CHECKOUT = Path(__file__).resolve().parent.parent


def candidate_roots() -> list[Path]:
    """Where the data root is looked for, in order: ``$DFRMOT_DATA`` alone when set, else
    ``./../shared/data/kitti/training`` and ``<package checkout>/../shared/data/kitti/training``."""
    env = os.environ.get(ENV_VAR)
    if env:
        return [Path(env).expanduser()]
    return list(dict.fromkeys([Path.cwd() / RELATIVE, (_CHECKOUT / RELATIVE).resolve()]))


def default_data_root() -> Path:
    """The first candidate root that holds the data, else the first candidate (see
    :func:`missing_data_message` for what to tell the user then)."""
    roots = candidate_roots()
    return next((r for r in roots if data_available(r)), roots[0])


def data_available(root: Path | None = None) -> bool:
    root = default_data_root() if root is None else Path(root)
    return (root / "label_02").is_dir() and (root / "detections").is_dir()


def missing_data_message(root: Path | None = None) -> str:
    """A message naming where the data was looked for."""
    if root is not None:
        return f"no label_02/ or detections/ under {root} (the KITTI tracking training root)"
    if os.environ.get(ENV_VAR):
        return f"${ENV_VAR} = {os.environ[ENV_VAR]} holds no label_02/ or detections/"
    looked = " or ".join(str(r) for r in candidate_roots())
    return f"KITTI data not found: set ${ENV_VAR} to the KITTI tracking training root (looked in {looked})"


def default_compile_cache() -> Path:
    """The folder ``dfrmot`` keeps compiled tracker programs in when ``$DFRMOT_COMPILE_CACHE`` is unset:
    ``$XDG_CACHE_HOME/dfrmot_jax/xla`` (``~/.cache/dfrmot_jax/xla`` without it)."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "dfrmot_jax" / "xla"
