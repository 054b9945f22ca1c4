"""Decode CAN frames with the PyPI package cantools, the reference DBC decoder.

usage: cantools_decode.py DBC FRAMES.jsonl OUT.jsonl
FRAMES: one {"id": int, "extended": bool, "data": "hex"} per line.
OUT: one {"name": str, "signals": {name: value}} per frame (null when cantools has no message).

cantools rejects opendbc files as shipped (shared/data/README.md): comment statements that do
not follow the DBC grammar, and pseudo messages with 11-bit-flagged ids above 0x7FF. Those are
removed from a copy of the text first; they carry no signal definitions a frame can use.
"""
import json
import re
import sys

import cantools


def cleaned(text):
    text = re.sub(r'^CM_ .*?";[ \t]*$', "", text, flags=re.M | re.S)
    out, skip = [], False
    for line in text.splitlines():
        m = re.match(r"^BO_ (\d+) ", line)
        if m:
            mid = int(m.group(1))
            skip = 0x7FF < mid < 0x80000000
        elif not line.startswith(" SG_"):
            skip = False
        if skip:
            continue
        m = re.match(r"^(VAL_|BA_ \"\w+\" BO_|BA_ \"\w+\" SG_|SIG_VALTYPE_) (\d+) ", line)
        if m and 0x7FF < int(m.group(2)) < 0x80000000:
            continue
        out.append(line)
    return "\n".join(out) + "\n"


def main():
    dbc_path, frames_path, out_path = sys.argv[1:4]
    with open(dbc_path, encoding="cp1252") as f:
        db = cantools.database.load_string(cleaned(f.read()), database_format="dbc", strict=False)
    with open(frames_path) as f, open(out_path, "w") as out:
        for line in f:
            fr = json.loads(line)
            try:
                msg = next(m for m in db.messages if m.frame_id == fr["id"] and m.is_extended_frame == fr["extended"])
            except StopIteration:
                out.write("null\n")
                continue
            data = bytes.fromhex(fr["data"])
            try:
                values = msg.decode(data, decode_choices=False, scaling=True, allow_truncated=True)
            except cantools.database.errors.DecodeError as e:
                # cantools cannot unpack messages whose signals overlap (opendbc has a few).
                out.write(json.dumps({"name": msg.name, "error": str(e)}) + "\n")
                continue
            out.write(json.dumps({"name": msg.name, "signals": {k: float(v) for k, v in values.items()}}) + "\n")


if __name__ == "__main__":
    main()
