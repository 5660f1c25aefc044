"""The ``dfrmot`` subcommands: their names in the order ``dfrmot --help`` lists them, each one's line
of help, and the module that registers its parser (``add_parser(sub)``). A light module: the parser
lists every command from this table without importing the commands' modules (:mod:`dfrmot_jax.cli`
imports only the named command's parser module, and that command's own module when it runs)."""

from __future__ import annotations

from ..trackers.registry import CONFIGS, DEFAULT_FAMILY, family_names

__all__ = ["HELP", "PARSERS", "FAMILIES", "FAMILY_NAMES", "OBJECTIVES"]

#: the tracker families, as the help names them (every family of the registry, ``trackers.registry``,
#: NumPy only); a sweep file picks one with ``[options] family``
FAMILIES = ", ".join(f"{n} ({CONFIGS[n].title}{', the default' if n == DEFAULT_FAMILY else ''})" for n in family_names())
#: the families' names alone, "dfr, ab3dmot, ..."
FAMILY_NAMES = ", ".join(family_names())
#: what an ``--objective`` may name, as the help says it (``metrics.columns.OBJECTIVE_FIELDS``)
OBJECTIVES = ("HOTA (default), MOTA, IDF1, AssA, DetA, IDSW, Frag (minimised), ...; AB3DMOT's sAMOTA, AMOTA, AMOTP, "
              "ab3dmot_MOTA, ... (sweeps scored with [metrics] ab3dmot; not cross-validated)")

#: command -> its line in ``dfrmot --help`` (each command's ``add_parser`` registers it with this help)
HELP = {
    "track": "track a KITTI split and write one result file per sequence",
    "demo": "a small parameter sweep on a synthetic scene, with its HTML report (no data needed)",
    "eval": "evaluate KITTI tracking result folders (TrackEval's KITTI 2D box HOTA/CLEAR/Identity; AB3DMOT's "
            "sAMOTA/AMOTA with --metrics ab3dmot)",
    "compare": "compare two result folders: per-sequence differences, paired bootstrap intervals over sequences",
    "sweep": f"run a sweep file of any tracker family ({FAMILY_NAMES}; tracking + metrics for every config), "
             "resumable",
    "tune": f"tune a sweep file's parameters (any tracker family: {FAMILY_NAMES}) with batched Optuna search (+ "
            "gradient refinement)",
    "report": f"best configs, baseline, sensitivity and cross-validation of a sweep or tune directory (any "
              f"tracker family: {FAMILY_NAMES})",
    "lidar": "simulate LiDAR scans; lift 2D detections to 3D boxes from scans",
}

#: command -> the module (of ``dfrmot_jax.cli``) whose ``add_parser(sub)`` registers it: ``CMD_parser``,
#: which imports nothing heavy (``dfrmot CMD --help`` imports neither the command's module nor what it
#: runs: ``track``'s lists every parameter, option and preset from ``config`` alone); its ``func`` imports
#: the command's own module, ``CMD``, when it runs (``errors.run_later``)
PARSERS = {name: f"{name}_parser" for name in HELP}
