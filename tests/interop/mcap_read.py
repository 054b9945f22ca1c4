"""Read an MCAP with the PyPI `mcap` package (CRC validation on) and decode every message's CDR
with `rosbags`, using the ros2msg schema stored in the file. Prints one JSON document:
{"profile", "library", "channels": {topic: {"type", "encoding", "count"}}, "metadata": {...},
 "attachments": [...], "messages": {topic: [decoded, ...]}} (messages only for --decode topics).

usage: mcap_read.py FILE [--decode TOPIC ...] [--limit N]
"""
import json
import sys
from collections import defaultdict

from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

SEP = "=" * 80 + "\n"


def register(store, name, schema):
    """Register a type and its dependencies from an MCAP ros2msg schema."""
    parts = schema.split(SEP)
    types = {}
    types.update(get_types_from_msg(parts[0], name))
    for p in parts[1:]:
        head, _, body = p.partition("\n")
        dep = head.replace("MSG: ", "").strip()
        pkg, typ = dep.split("/")
        types.update(get_types_from_msg(body, f"{pkg}/msg/{typ}"))
    store.register(types)


def plain(v):
    # NaN (an angle a message lacks) as null: JSON has no NaN.
    if isinstance(v, float) and v != v:
        return None
    if hasattr(v, "__dataclass_fields__") or hasattr(v, "__msgtype__"):
        return {k: plain(getattr(v, k)) for k in v.__dataclass_fields__ if k != "__msgtype__"}
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def main():
    path = sys.argv[1]
    decode = set()
    limit = 1_000_000
    count_scan_packets = False
    args = sys.argv[2:]
    while args:
        a = args.pop(0)
        if a == "--count-scan-packets":
            count_scan_packets = True
        elif a == "--decode":
            decode.add(args.pop(0))
        elif a == "--limit":
            limit = int(args.pop(0))
    store = get_typestore(Stores.EMPTY)
    registered = set()
    out = {"channels": {}, "metadata": {}, "attachments": [], "messages": defaultdict(list)}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        header = reader.get_header()
        out["profile"] = header.profile
        out["library"] = header.library
        summary = reader.get_summary()
        out["chunks"] = [
            {"start": c.message_start_time, "end": c.message_end_time, "compression": c.compression,
             "offset": c.chunk_start_offset, "length": c.chunk_length}
            for c in (summary.chunk_indexes if summary else [])
        ]
        counts = defaultdict(int)
        scan_packets = 0
        for schema, channel, message in reader.iter_messages():
            counts[channel.topic] += 1
            if count_scan_packets and schema.name == "velodyne_msgs/msg/VelodyneScan":
                # Read only the sequence length: header stamp (8), frame_id (u32 + bytes), align 4.
                d = message.data
                n = int.from_bytes(d[12:16], "little")
                off = 16 + n
                off += (4 - (off - 4) % 4) % 4
                scan_packets += int.from_bytes(d[off:off + 4], "little")
            out.setdefault("last_log_time", 0)
            out["last_log_time"] = max(out["last_log_time"], message.log_time)
            out["channels"][channel.topic] = {"type": schema.name, "schema_encoding": schema.encoding, "encoding": channel.message_encoding}
            if channel.topic in decode and len(out["messages"][channel.topic]) < limit:
                if schema.name not in registered:
                    register(store, schema.name, schema.data.decode())
                    registered.add(schema.name)
                msg = store.deserialize_cdr(message.data, schema.name)
                d = plain(msg)
                if schema.name == "sensor_msgs/msg/PointCloud2":
                    # Keep the JSON small: the data's length and its first point.
                    raw = bytes(msg.data)
                    d["data"] = {"len": len(raw), "first": list(raw[:msg.point_step])}
                d["_log_time"] = message.log_time
                d["_publish_time"] = message.publish_time
                out["messages"][channel.topic].append(d)
        for topic, n in counts.items():
            out["channels"][topic]["count"] = n
        out["scan_packets"] = scan_packets
        f.seek(0)
        reader = make_reader(f, validate_crcs=True)
        for m in reader.iter_metadata():
            out["metadata"][m.name] = dict(m.metadata)
        for a in reader.iter_attachments():
            out["attachments"].append({"name": a.name, "media_type": a.media_type, "size": len(a.data)})
    json.dump(out, sys.stdout)


if __name__ == "__main__":
    main()
