"""SLAM on real robots' logs, scored by the relations metric of Kümmerle et al. 2009: odometry, scan matching, grid SLAM, pose graph.

Each log (a CARMEN log, a ROS bag or a homing run log; by default the five
Radish logs in ``../shared/datasets/carmen/``) is replayed through every
method of :mod:`homing.logs.offline`, and each trajectory is scored with
:mod:`homing.mapping.relations`: against the log's relations file
(``--relations FILE``, paired with the logs in order, or ``LOG.relations``
beside a log) or, without one, against relations drawn from the log's own
corrected poses (a corrected log's ``ref`` records — an RBPF's estimate,
so a floor of a few centimetres is the reference's own error, not the
method's). Per log and method: translational error [m] and rotational
error [deg], mean ± std and maximum, the same of the squared errors [m²,
deg²], the relations scored (of them, interpolated) and those left
unmatched with each one's reason, and the method's wall and CPU time per
scan. A relations file on another clock than its log (absolute against
relative stamps) is moved onto the log's clock when one offset clearly
does it (:func:`homing.mapping.relations.time_offset`), or given one with
``--relations-offset``; otherwise the command stops with the offset needed.

A method that fails on a log (an exception inside it) is reported in its
row and under ``failed`` in the JSON with the method's name; the command
exits 0 when every log was read, 1 when a log could not be.

Published figures (Kümmerle et al. 2009, their relations, the uncorrected
logs; translational error [m]) are printed as reference rows where a log's
name matches: ACES, Intel, Freiburg 079, MIT CSAIL.

Runs go to ``--engine`` (``local`` by default: time per scan is measured,
and two runs on a 2-core machine would slow each other).
"""

from __future__ import annotations

import argparse
import math
import traceback
from pathlib import Path
from typing import Any

from homing.benchmarks.common import print_table, progress_bar, write_json
from homing.benchmarks.engine import (
    Outcome,
    add_engine_arguments,
    engine_from_args,
    failures_table,
    run_jobs,
)

SHARED_LOGS = Path(__file__).resolve().parent.parent.parent / "shared" / "datasets" / "carmen"
METHOD_LABELS = {"odometry": "odometry", "scan_matching": "scan match", "grid": "grid SLAM", "graph": "pose graph",
                 "online": "online SLAM"}
PUBLISHED = {  # Kümmerle et al. 2009, translational error [m]: scan matching, RBPF (gmapping), graph mapping
    "aces": ((0.173, 0.614), (0.060, 0.049), (0.044, 0.044)),
    "intel": ((0.220, 0.296), (0.070, 0.083), (0.031, 0.026)),
    "freiburg-079": ((0.258, 0.427), (0.061, 0.044), (0.056, 0.042)),
    "mit-csail": ((0.106, 0.325), (0.049, 0.049), (0.004, 0.009)),
}


def log_name(path: str | Path) -> str:
    """A log's short name: its file name less ``.gz``, ``.log`` and ``-corrected``."""
    name = Path(path).name
    for suffix in (".gz", ".log", ".clf", ".bag", ".mcap", ".db3"):
        name = name.removesuffix(suffix)
    return name.removesuffix("-corrected")


def score_method(log_path: str, method: str, relations_path: str | None, offset: float = 0.0) -> dict[str, Any]:
    """One log through one method, scored (JSON keys of the issue); raises UserError on a bad log.

    An exception inside the method is caught and returned as ``{"failed": …}``
    (its type, message and where it was raised), so that one method's failure
    costs neither the sweep nor the other methods' figures.
    """
    from homing.logs import open_log
    from homing.logs.offline import run_method
    from homing.mapping.relations import read_relations, relations_from_poses, score, shifted

    from homing.errors import UserError

    log = open_log(log_path)
    if relations_path:
        relations, source = shifted(read_relations(relations_path), offset), "file"
    else:
        ref = log.reference()
        if not ref:
            raise UserError("no relations file and no corrected poses to draw relations from", log_path)
        relations, source = relations_from_poses([t for t, _ in ref], [p for _, p in ref]), "corrected poses"
    try:
        result = run_method(log, method)
    except Exception as err:  # a method's failure is a figure of the sweep, not its end
        where = traceback.extract_tb(err.__traceback__)[-1]
        return {"failed": f"{type(err).__name__}: {' '.join(str(err).split())} "
                          f"({Path(where.filename).name}:{where.lineno})"}
    e = score(relations, result.stamps, result.poses)
    return {"trans_err_mean_m": e.trans_mean, "trans_err_std_m": e.trans_std, "trans_err_max_m": e.trans_max,
            "rot_err_mean_deg": e.rot_mean, "rot_err_std_deg": e.rot_std, "rot_err_max_deg": e.rot_max,
            "trans_sq_err_mean_m2": e.trans_sq_mean, "trans_sq_err_std_m2": e.trans_sq_std,
            "trans_sq_err_max_m2": e.trans_sq_max, "rot_sq_err_mean_deg2": e.rot_sq_mean,
            "rot_sq_err_std_deg2": e.rot_sq_std, "rot_sq_err_max_deg2": e.rot_sq_max,
            "seconds_per_scan": result.seconds_per_scan, "cpu_seconds_per_scan": result.cpu_seconds_per_scan,
            "relations": e.n, "relations_interpolated": e.interpolated, "relations_missing": e.missing,
            "relations_unmatched": [{"t1": u.relation.t1, "t2": u.relation.t2, "reason": u.reason}
                                    for u in e.unmatched],
            "relations_from": source, "relations_offset_s": offset, "scans": len(result.stamps), **result.info}


def scan_stamps(log_path: str) -> list[float]:
    """The stamps [s] of a log's scans, ascending (the clock its relations must be on)."""
    from homing.logs import open_log

    return sorted(float(r["t"]) for r in open_log(log_path).of_kind("scan"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("logs", nargs="*", metavar="LOG",
                        help="logs to score (default: the five in ../shared/datasets/carmen/ when present)")
    parser.add_argument("--relations", action="append", metavar="FILE",
                        help="a relations file (t1 t2 x y z roll pitch yaw per line) per LOG, in order")
    parser.add_argument("--relations-offset", action="append", type=float, metavar="SECONDS",
                        help="seconds to subtract from each relations file's stamps, in order (default: found, "
                             "when the file and its log count time differently)")
    parser.add_argument("--methods", nargs="+", default=list(METHOD_LABELS), choices=list(METHOD_LABELS),
                        help="methods to run (default: all)")
    add_engine_arguments(parser, workers=1)


def run(args: argparse.Namespace) -> int:
    from homing.errors import UserError

    engine = engine_from_args(args)
    logs = list(args.logs)
    if not logs and SHARED_LOGS.is_dir():
        logs = sorted(str(p) for p in SHARED_LOGS.glob("*.log.gz"))
    if not logs:
        raise UserError("no logs given, and no ../shared/datasets/carmen/ beside the repository")
    relations = list(args.relations or [])
    if len(relations) > len(logs):
        raise UserError(f"{len(relations)} --relations files for {len(logs)} logs")
    for i, log in enumerate(logs):
        if not Path(log).exists():
            raise UserError("no such log", log)
        beside = Path(str(log).removesuffix(".gz").removesuffix(".log") + ".relations")
        if i >= len(relations):
            relations.append(str(beside) if beside.is_file() else None)
        elif not Path(relations[i]).is_file():
            raise UserError("no such relations file", relations[i])
    offsets = _offsets(logs, relations, list(args.relations_offset or []))
    jobs = [(log, m, relations[i], offsets[i]) for i, log in enumerate(logs) for m in args.methods]
    with progress_bar("slam-logs", len(jobs)) as advance:
        outcomes = run_jobs(score_method, jobs, engine, lambda o: advance(_describe(o)))
    out, rows = summarise(outcomes)
    print_table("SLAM on real logs: relation errors (Kümmerle et al. 2009), mean±std and max",
                ["log", "method", "trans m", "max m", "rot °", "max °", "ms/scan", "cpu ms"], rows)
    print_table("Squared errors (mean±std) and the relations: scored (interpolated), unmatched",
                ["log", "method", "trans² m²", "rot² °²", "scored", "interp", "unmatched"], _second(out))
    _print_unmatched(out)
    write_json(args.json, out)
    return 0 if not out["failed"] else 1


def _offsets(logs: list[str], relations: list[str | None], given: list[float]) -> list[float]:
    """Per log, [s] to subtract from its relations file's stamps: given, or found (UserError if ambiguous)."""
    from homing.mapping.relations import read_relations, time_offset

    from homing.errors import UserError

    if len(given) > len([r for r in relations if r]):
        raise UserError(f"{len(given)} --relations-offset values for {len([r for r in relations if r])} relations files")
    out, k = [], 0
    for log, rel in zip(logs, relations, strict=True):
        if not rel:
            out.append(0.0)
            continue
        relations_read = read_relations(rel)  # a malformed file stops here, with its line
        if k < len(given):
            out.append(given[k])
        else:
            out.append(time_offset(relations_read, scan_stamps(log), rel))
        k += 1
    return out


def summarise(outcomes: list[Outcome]) -> tuple[dict[str, Any], list[list[Any]]]:
    """The JSON (log → method → figures, ``failed`` and ``method_failures``) and the table's rows (published after each log)."""
    out: dict[str, Any] = {}
    failures: list[dict[str, Any]] = []
    rows: list[list[Any]] = []
    last = None
    for o in outcomes:
        log, method = log_name(o.job[0]), o.job[1]
        if last is not None and log != last:
            rows += _published(last)
        last = log
        if not o.ok:
            rows.append([log, METHOD_LABELS[method], f"failed: {o.error}"[:60]] + [""] * 5)
            continue
        r = o.result
        out.setdefault(log, {})[method] = r
        if "failed" in r:
            failures.append({"log": log, "method": method, "error": r["failed"]})
            rows.append([log, METHOD_LABELS[method], f"failed: {r['failed']}"[:60]] + [""] * 5)
            continue
        rows.append([log, METHOD_LABELS[method], _pm(r["trans_err_mean_m"], r["trans_err_std_m"], 3),
                     _num(r["trans_err_max_m"], 3), _pm(r["rot_err_mean_deg"], r["rot_err_std_deg"], 2),
                     _num(r["rot_err_max_deg"], 1), _num(1e3 * r["seconds_per_scan"], 1),
                     _num(1e3 * r["cpu_seconds_per_scan"], 1)])
    if last is not None:
        rows += _published(last)
    out["failed"] = failures_table(outcomes)  # logs that could not be read
    out["method_failures"] = failures  # a method that raised on a log that was read
    return out, rows


def _second(out: dict[str, Any]) -> list[list[Any]]:
    rows = []
    for log, methods in out.items():
        if not isinstance(methods, dict):
            continue
        for method, r in methods.items():
            if "failed" in r:
                continue
            rows.append([log, METHOD_LABELS[method], _pm(r["trans_sq_err_mean_m2"], r["trans_sq_err_std_m2"], 4),
                         _pm(r["rot_sq_err_mean_deg2"], r["rot_sq_err_std_deg2"], 2), r["relations"],
                         r["relations_interpolated"], r["relations_missing"]])
    return rows


def _print_unmatched(out: dict[str, Any], most: int = 3) -> None:
    """Each log's unmatched relations (the first method's: the stamps are the log's), ``most`` reasons at most."""
    for log, methods in out.items():
        if not isinstance(methods, dict):
            continue
        first = next((r for r in methods.values() if "failed" not in r), None)
        if first is None or not first["relations_unmatched"]:
            continue
        missed = first["relations_unmatched"]
        print(f"{log}: {len(missed)} relations unmatched, e.g. " +
              "; ".join(f"{u['t1']:.3f}→{u['t2']:.3f}: {u['reason']}" for u in missed[:most]))


def _published(log: str) -> list[list[Any]]:
    fig = PUBLISHED.get(log)
    if fig is None:
        return []
    labels = ("SM (pub.)", "RBPF (pub.)", "graph (pub.)")
    return [[log, label, _pm(m, s, 3), "–", "–", "–", "–", "–"] for label, (m, s) in zip(labels, fig, strict=True)]


def _num(v: float, decimals: int) -> str:
    """``v`` with ``decimals`` decimals below 10, one above (the table must fit 80 columns)."""
    return "–" if math.isnan(v) else (f"{v:.{decimals}f}" if abs(v) < 10 else f"{v:.1f}")


def _pm(mean: float, std: float, decimals: int) -> str:
    return f"{_num(mean, decimals)}±{_num(std, decimals)}"


def _describe(o: Outcome) -> str:
    head = f"{log_name(o.job[0])} {o.job[1]}"
    return f"{head}: failed" if not o.ok or "failed" in o.result else f"{head}: {o.result['trans_err_mean_m']:.3f} m"
