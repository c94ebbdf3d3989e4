"""Log formats in and out: CARMEN logs and ROS 1/2 bags read into homing's run-log model, ROS 2 bags in MCAP written.

:func:`open_log` reads any log homing knows — its own run logs
(:mod:`homing.logs.runlog`), CARMEN logs (:mod:`homing.logs.carmen`),
ROS 1 ``.bag`` and ROS 2 bags (:mod:`homing.logs.rosbag`) — as a
:class:`~homing.logs.runlog.RunLog`, so that offline SLAM, replay and
export treat them alike. :mod:`homing.logs.mcap_export` writes any of them
as a ROS 2 bag in MCAP for Foxglove and ``ros2 bag play``.
"""

from __future__ import annotations

from pathlib import Path

from homing.logs.runlog import MAGIC, RunLog

from homing.errors import UserError

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
MAGIC_PREFIX = MAGIC.split(b" ")[0] + b" "  # "HOMINGLOG "


def log_format(path: str | Path) -> str:
    """``"homing"``, ``"rosbag"`` or ``"carmen"``: what the file at ``path`` is, from its suffix and first bytes."""
    p = Path(path)
    if p.is_dir():
        if (p / "metadata.yaml").is_file():
            return "rosbag"
        raise UserError("a folder that is not a ROS 2 bag (no metadata.yaml)", p)
    if p.suffix in BAG_SUFFIXES:
        return "rosbag"
    try:
        with p.open("rb") as f:
            head = f.read(len(MAGIC))
    except OSError as err:
        raise UserError(f"cannot read log: {err.strerror or err}", p) from None
    return "homing" if head.startswith(MAGIC_PREFIX) else "carmen"  # any version: RunLog says if it is too new


def open_log(path: str | Path, scan_topic: str | None = None, odom_topic: str | None = None,
             salvage: bool = False) -> RunLog:
    """Any log homing reads, as a RunLog (``scan_topic``/``odom_topic`` choose a bag's topics; ``salvage``: a
    damaged homing run log is read up to the damage, see :class:`homing.logs.runlog.RunLog`)."""
    kind = log_format(path)
    if kind == "homing":
        return RunLog(path, salvage=salvage)
    if kind == "rosbag":
        from homing.logs.rosbag import read_bag

        return read_bag(path, scan_topic, odom_topic)
    from homing.logs.carmen import read_carmen

    return read_carmen(path)
