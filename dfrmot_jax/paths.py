"""Where the KITTI data lives.

The data are never part of the repository. ``DFRMOT_DATA`` names the KITTI tracking *training*
root (the folder that holds ``label_02/``, ``calib/`` and ``detections/``); without it we look for
``../shared/data/kitti/training`` beside the project checkout.
"""

from __future__ import annotations

import os
from pathlib import Path

ENV_VAR = "DFRMOT_DATA"
_PROJECT_ROOT = Path(__file__).resolve().parent.parent


def default_data_root() -> Path:
    """The KITTI training root: ``$DFRMOT_DATA`` or ``<checkout>/../shared/data/kitti/training``."""
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env).expanduser()
    return _PROJECT_ROOT.parent / "shared" / "data" / "kitti" / "training"


def data_available(root: Path | None = None) -> bool:
    root = default_data_root() if root is None else Path(root)
    return (root / "label_02").is_dir() and (root / "detections").is_dir()
