"""The trial's topics as an MCAP file that ``ros2 bag`` (rosbag2_storage_mcap) and Foxglove read.

``BagWriter`` writes ROS 2 messages as CDR (``rclpy.serialization``) with ``ros2msg`` schemas
(the message definition and its dependencies, as rosbag2 stores them) into zstd-compressed,
indexed chunks (the mcap writer's ``compression``, ``chunk_size`` and message indexes, as
rosbag2's MCAP storage writes them: readers that seek, like rerun's MCAP import, need the
chunks). Each ``write`` (a message) and ``write_all`` (a message and its ``standard_views``)
ends its chunk (``Writer.flush``) and is fsync'ed: a crash loses at most what is being written.
``close()`` writes the summary (chunk indexes, statistics) and footer. ``read_bag`` reads a
closed file, or a crashed one up to its last whole record; ``recover_bag`` writes a closed copy
of a crashed file.

A bag in a trial record folder (one with ``config.json``) is listed in the record when it is
started: an ``mcap_started`` line in ``events.jsonl`` names the file (``topics.mcap``, then
``topics.<k>.mcap`` for the k-th resume); ``recorded_bags`` gives a record's files in order.
``merge_bags`` makes them one ``topics.mcap`` when a resumed run ends: every part's schemas,
channels and messages, in order, written beside them, read back and counted; only then does it
replace ``topics.mcap``, list the merge (``mcap_merged``: ``file``, ``parts``, ``messages``) and
remove the other parts. A merge that fails keeps every part and lists why
(``mcap_merge_failed``).

The record folder (PNG + JSONL, ``trial/record.py``) stays the ground truth; the bag is for ROS tools.
"""

from __future__ import annotations

import contextlib
import copy
import importlib
import os
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any
from collections.abc import Iterator

from mcap.stream_reader import StreamReader
from mcap.records import Channel, Message, Schema
from mcap.writer import CompressionType, Writer

from ..core.errors import InputError
from ..core.outputs import WriteError

_PRIMITIVES = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
               "int32", "uint32", "int64", "uint64", "string", "wstring"}
_SEP = "=" * 80
TOUCH_TOPIC = "/tactex/touch"   # channel of the full touches (tactex/msg/Touch, no-contact frame
#                                 included); not a published topic, the action result's touch
COMPRESSION = CompressionType.ZSTD   # rosbag2's MCAP storage default (its "zstd_fast" preset)
CHUNK_BYTES = 1024 * 1024       # [bytes] the mcap writer's default chunk size: a chunk also
#                                 ends at every write (one touch and its views: about 2.3 MB)
STARTED_EVENT = "mcap_started"  # events.jsonl: a bag of the trial was started (``file``)
MERGED_EVENT = "mcap_merged"    # events.jsonl: the parts (``parts``) are now ``file``
MERGE_FAILED_EVENT = "mcap_merge_failed"   # events.jsonl: the parts were kept (``reason``)
BAG_FILE = "topics.mcap"        # a trial record's bag (its first part before a merge)


def _share_dirs() -> list[Path]:
    roots = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    return [Path(r) / "share" for r in roots] + [Path(sys.prefix) / "share"]


def _msg_text(pkg: str, kind: str, name: str) -> str:
    for share in _share_dirs():
        f = share / pkg / kind / f"{name}.{kind}"
        if f.is_file():
            return f.read_text()
    raise InputError(f"message definition {pkg}/{kind}/{name} not found under "
                     f"{[str(s) for s in _share_dirs()]}")


def _deps(pkg: str, text: str) -> list[str]:
    """Message types a definition refers to, as ``pkg/Name``."""
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or line.startswith("---"):
            continue
        if "=" in line:
            continue                                   # a constant: always a primitive
        typ = line.split()[0]
        typ = re.sub(r"\[.*\]$", "", typ)
        typ = re.sub(r"<=\d+$", "", typ)
        if typ in _PRIMITIVES:
            continue
        if typ == "Header":
            typ = "std_msgs/Header"
        elif "/" not in typ:
            typ = f"{pkg}/{typ}"
        out.append(typ.replace("/msg/", "/"))
    return out


def message_definition(type_name: str) -> str:
    """The full ``ros2msg`` definition of ``pkg/msg/Name``: its text, then every dependency
    once, each after a line of 80 '=' and ``MSG: pkg/Name`` (rosbag2's layout)."""
    pkg, _, name = type_name.split("/")
    main = _msg_text(pkg, "msg", name)
    parts, seen, todo = [], {f"{pkg}/{name}"}, _deps(pkg, main)
    while todo:
        dep = todo.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        dpkg, dname = dep.split("/")
        text = _msg_text(dpkg, "msg", dname)
        parts.append(f"{_SEP}\nMSG: {dep}\n{text}")
        todo += _deps(dpkg, text)
    return "\n".join([main.rstrip("\n")] + [p.rstrip("\n") for p in parts]) + "\n"


def type_name(msg: Any) -> str:
    """``pkg/msg/Name`` of a generated ROS 2 message instance."""
    mod = type(msg).__module__.split(".")             # e.g. tactex.msg._touch
    return f"{mod[0]}/{mod[1]}/{type(msg).__name__}"


def _writer(f) -> Writer:
    """The mcap writer of every bag this module writes: chunked, compressed, indexed."""
    return Writer(f, chunk_size=CHUNK_BYTES, compression=COMPRESSION)


def recorded_bags(folder: str | Path) -> list[Path]:
    """The bags a trial record lists (``mcap_started`` events), in the order they were
    started; a listed file that is gone is left out."""
    from ..trial.record import read_record
    events = read_record(folder, images=False).get("events") or []
    names: list[str] = []
    for e in events:
        f = e.get("file")
        if not isinstance(f, str):
            continue
        if e.get("event") == STARTED_EVENT and f not in names:
            names.append(f)
        elif e.get("event") == MERGED_EVENT:      # the parts are one file now, at the first's place
            parts = [p for p in e.get("parts") or [] if p in names]
            at = names.index(parts[0]) if parts else len(names)
            names = [n for n in names if n not in parts and n != f]
            names.insert(min(at, len(names)), f)
    return [Path(folder) / n for n in names if (Path(folder) / n).is_file()]


def count_messages(path: str | Path) -> int:
    """The whole messages of an MCAP file (a crashed one: up to its torn tail)."""
    return sum(isinstance(r, Message) for r in _records(Path(path)))


def _merge_into(parts: list[Path], out: Path) -> int:
    """Write every whole message of ``parts`` (in order; each part's schemas and channels
    registered once, the same schema or channel in two parts shared) into ``out``, closed and
    fsync'ed; returns the messages written."""
    n = 0
    with open(out, "wb") as f:
        w = _writer(f)
        w.start(profile="ros2", library="tactex")
        schema_ids: dict[tuple[str, str, bytes], int] = {}
        channel_ids: dict[tuple[str, str, int, tuple], int] = {}
        for part in parts:
            sids: dict[int, int] = {}
            cids: dict[int, int] = {}
            for r in _records(part):
                if isinstance(r, Schema):
                    key = (r.name, r.encoding, bytes(r.data))
                    if key not in schema_ids:
                        schema_ids[key] = w.register_schema(r.name, r.encoding, r.data)
                    sids[r.id] = schema_ids[key]
                elif isinstance(r, Channel):
                    sid = sids.get(r.schema_id, 0)
                    ckey = (r.topic, r.message_encoding, sid, tuple(sorted(r.metadata.items())))
                    if ckey not in channel_ids:
                        channel_ids[ckey] = w.register_channel(r.topic, r.message_encoding,
                                                               sid, dict(r.metadata))
                    cids[r.id] = channel_ids[ckey]
                elif isinstance(r, Message) and r.channel_id in cids:
                    w.add_message(cids[r.channel_id], log_time=r.log_time, data=r.data,
                                  publish_time=r.publish_time, sequence=r.sequence)
                    n += 1
        w.finish()
        f.flush()
        os.fsync(f.fileno())
    return n


def merge_bags(folder: str | Path) -> Path | None:
    """One ``topics.mcap`` of the bags a trial record lists (module doc): the merged file, the
    only bag when there is one, None when there is none or the merge failed (the parts are
    kept and ``mcap_merge_failed`` says why; nothing recorded is lost)."""
    from ..trial.record import append_event
    d = Path(folder)
    parts = recorded_bags(d)
    if len(parts) < 2:
        return parts[0] if parts else None
    tmp = d / (BAG_FILE + ".merging")
    names = [p.name for p in parts]
    try:
        expected = sum(count_messages(p) for p in parts)
        n = _merge_into(parts, tmp)
        got = count_messages(tmp)
        if not n == got == expected:
            raise WriteError(f"the merged file holds {got} messages, the parts {expected}")
        os.replace(tmp, d / BAG_FILE)
    except Exception as exc:  # noqa: BLE001 - any failure keeps every part as it is
        with contextlib.suppress(OSError):
            tmp.unlink()
        append_event(d, {"event": MERGE_FAILED_EVENT, "parts": names, "reason": str(exc),
                         "time": time.time()})
        return None
    append_event(d, {"event": MERGED_EVENT, "file": BAG_FILE, "parts": names, "messages": n,
                     "time": time.time()})
    for p in parts:
        if p.name != BAG_FILE:
            with contextlib.suppress(OSError):
                p.unlink()
    return d / BAG_FILE


class BagWriter:
    """MCAP writer of ROS 2 messages; thread-safe; every write ends its chunk, flushed and
    fsync'ed. In a trial record folder the file is listed in the record (module doc).

    A write that fails (disk full, file-size limit, I/O error) raises WriteError naming the
    file once; the writer is then ``failed`` (the reason) and takes no more messages, and
    ``close()`` never raises: the file keeps every whole message written before (``read_bag``
    / ``recover_bag`` read it)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        self.closed = False
        self.failed: str | None = None
        try:
            self._f = open(self.path, "wb")  # noqa: SIM115 - open until close()
        except OSError as exc:
            raise WriteError(f"could not write {str(self.path)!r}: "
                             f"{exc.strerror or exc}") from None
        self._w = _writer(self._f)
        self._channels: dict[tuple[str, str], int] = {}
        self._schemas: dict[str, int] = {}
        with self._lock:
            self._guard(lambda: self._w.start(profile="ros2", library="tactex"))
        if (self.path.parent / "config.json").is_file():       # a trial record: list it
            from ..trial.record import append_event
            append_event(self.path.parent, {"event": STARTED_EVENT, "file": self.path.name,
                                            "time": time.time()})

    def _sync(self) -> None:
        self._f.flush()
        os.fsync(self._f.fileno())

    def _guard(self, step) -> None:
        """Run a write step and sync; on an OSError the writer stops (``failed``) and the file
        is closed without its summary (WriteError names it)."""
        try:
            step()
            self._sync()
        except OSError as exc:
            self.failed = f"{exc.strerror or exc}"
            self.closed = True
            with contextlib.suppress(OSError):   # the buffered tail that could not be written
                self._f.close()
            raise WriteError(f"could not write {str(self.path)!r}: {self.failed}; the "
                             "MCAP copy stops here (whole messages before stay readable)") \
                from None

    def write(self, topic: str, msg: Any, t_ns: int) -> None:
        """Append ``msg`` on ``topic`` at ``t_ns`` [ns since the epoch] in a chunk of its own;
        nothing once closed or failed."""
        self._write_chunk([(topic, msg)], t_ns)

    def write_all(self, topic: str, msg: Any, t_ns: int) -> None:
        """``write`` the message and its ``standard_views`` at the same time, in one chunk."""
        self._write_chunk([(topic, msg), *standard_views(topic, msg)], t_ns)

    def _write_chunk(self, items: list[tuple[str, Any]], t_ns: int) -> None:
        """The messages ``items`` ((topic, message)) at ``t_ns``, then their chunk ended,
        flushed and fsync'ed."""
        from rclpy.serialization import serialize_message
        rows = [(topic, type_name(msg), serialize_message(msg)) for topic, msg in items]
        with self._lock:
            if self.closed:
                return

            def step() -> None:
                for topic, tn, data in rows:
                    if tn not in self._schemas:
                        self._schemas[tn] = self._w.register_schema(
                            tn, "ros2msg", message_definition(tn).encode())
                    key = (topic, tn)
                    if key not in self._channels:
                        self._channels[key] = self._w.register_channel(topic, "cdr",
                                                                       self._schemas[tn])
                    self._w.add_message(self._channels[key], log_time=t_ns, data=data,
                                        publish_time=t_ns)
                self._w.flush()
            self._guard(step)

    def close(self) -> None:
        """Write the summary and footer (a closed file is indexed for ``ros2 bag``). Never
        raises: a failure leaves the file as a crashed writer would (``failed`` says why)."""
        with self._lock:
            if self.closed:
                return
            try:
                self._guard(self._w.finish)
            except WriteError:
                return
            self.closed = True
            self._f.close()


MCAP_MAGIC = b"\x89MCAP0\r\n"     # the first 8 bytes of every MCAP file (MCAP spec, "Magic")


def _records(path: Path) -> Iterator[Any]:
    """The records of an MCAP file up to the last whole one (a crashed writer's torn tail and
    missing footer end the iteration)."""
    with open(path, "rb") as f:
        try:
            yield from StreamReader(f, validate_crcs=True).records
        except Exception:  # noqa: BLE001 - torn tail: every complete record was yielded
            return


def read_bag(path: str | Path, decode: bool = True) -> list[tuple[str, int, Any]]:
    """(topic, log time [ns], message) of every whole message, in file order. ``decode``:
    deserialise with the installed message classes (else the raw CDR bytes)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"bag {str(p)!r} not found")
    with open(p, "rb") as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise InputError(f"{str(p)!r} is not an MCAP file (it does not start with the "
                              "MCAP magic bytes)")
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    out = []
    for r in _records(p):
        if isinstance(r, Schema):
            schemas[r.id] = r
        elif isinstance(r, Channel):
            channels[r.id] = r
        elif isinstance(r, Message) and r.channel_id in channels:
            ch = channels[r.channel_id]
            msg: Any = r.data
            if decode:
                from rclpy.serialization import deserialize_message
                pkg, kind, name = schemas[ch.schema_id].name.split("/")
                cls = getattr(importlib.import_module(f"{pkg}.{kind}"), name)
                msg = deserialize_message(r.data, cls)
            out.append((ch.topic, r.log_time, msg))
    return out


def recover_bag(path: str | Path, out: str | Path) -> int:
    """Write a closed copy of a (crashed) bag with every whole message; returns their number."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    ids: dict[int, int] = {}
    sids: dict[int, int] = {}
    n = 0
    with open(out, "wb") as f:
        w = _writer(f)
        w.start(profile="ros2", library="tactex")
        for r in _records(Path(path)):
            if isinstance(r, Schema):
                schemas[r.id] = r
                sids[r.id] = w.register_schema(r.name, r.encoding, r.data)
            elif isinstance(r, Channel):
                channels[r.id] = r
                ids[r.id] = w.register_channel(r.topic, r.message_encoding, sids[r.schema_id])
            elif isinstance(r, Message) and r.channel_id in ids:
                w.add_message(ids[r.channel_id], log_time=r.log_time, data=r.data,
                              publish_time=r.publish_time)
                n += 1
        w.finish()
    return n


# ---------------------------------------------------------------------- standard views
# Viewers (Foxglove's Image and Plot panels, rerun's MCAP loader) show standard message types
# only; tactex/msg/Touch and ExplorationState are copied into these beside them.
TOUCH_IMAGE_VIEW = "/tactex/touch_image"      # sensor_msgs/Image rgb8 of every touch: the
#                                               explorer's touch_image_topic (its default)
NO_CONTACT_VIEW = "/tactex/touch_no_contact_image"   # sensor_msgs/Image: the touch's
#                                                      no-contact frame (when it has one)
EXTRA_IMAGE_VIEW = "/tactex/touch_extra_image"   # sensor_msgs/Image: each further in-contact
#                                                  frame of the touch's burst, at its own stamp
WRENCH_VIEW = "/tactex/touch_wrench"          # geometry_msgs/WrenchStamped: the press force
BELIEF_VIEW = "/tactex/belief/"               # + platform id: std_msgs/Float64 per comparison


def standard_views(topic: str, msg: Any) -> list[tuple[str, Any]]:
    """The standard messages a viewer shows for one of tactex's own (``topic`` is where
    ``msg`` goes): a touch (``TOUCH_TOPIC``, tactex/msg/Touch) gives its contact image, its
    further in-contact frames (``extra_images``, one message each) and its no-contact frame as
    ``sensor_msgs/Image`` (lossless rgb8, the camera's frame id) and its
    force as ``geometry_msgs/WrenchStamped`` (``force.z`` = the tared normal force the sensor
    presses with along its optical axis [N], in the camera's frame, stamped at capture); an
    exploration state (tactex/msg/ExplorationState) gives the belief in each comparison as one
    ``std_msgs/Float64`` on ``BELIEF_VIEW + platform id``. Any other message gives none."""
    tn = type_name(msg)
    if tn == "tactex/msg/Touch" and topic == TOUCH_TOPIC:
        from geometry_msgs.msg import WrenchStamped
        header = msg.image.header if msg.image.header.frame_id else msg.header
        out: list[tuple[str, Any]] = [(TOUCH_IMAGE_VIEW, msg.image)]
        out += [(EXTRA_IMAGE_VIEW, im) for im in msg.extra_images]
        if msg.no_contact_image.data:
            nc = copy.copy(msg.no_contact_image)
            if not nc.header.frame_id:
                nc.header = header
            out.append((NO_CONTACT_VIEW, nc))
        w = WrenchStamped(header=header)
        w.wrench.force.z = float(msg.contact_force_n)
        out.append((WRENCH_VIEW, w))
        return out
    if tn == "tactex/msg/ExplorationState":
        from std_msgs.msg import Float64
        return [(BELIEF_VIEW + pid, Float64(data=float(b)))
                for pid, b in zip(msg.platform_ids, msg.belief, strict=True)]
    return []
