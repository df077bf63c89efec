#!/usr/bin/env python3
"""Write the fuzz targets' seed inputs into fuzz/seeds/<target>/ (not committed: the committed
corpora are fuzz/corpus/<target>/, minimised from these seeds and what fuzzing found).

Seeds: the repo's scenarios and the TOML examples of docs/; bench configs from
docs/bench-config.md and tests; model files; the byte-exact frames of the protocol tests
(`b"..."` literals and `[0x.., ...]` arrays); small recordings: the Python-written fixtures
of tests/fixtures/ and the first messages of recordings/demo-null.mcap (needs the `mcap`
package: `$(bash scripts/pyenv.sh) fuzz/seed_corpora.py`); and the TOML inputs of
scripts/bad_inputs.py, broken and unbroken.
"""

import ast
import hashlib
import io
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "fuzz" / "seeds"


def put(target: str, data: bytes) -> None:
    d = OUT / target
    d.mkdir(parents=True, exist_ok=True)
    (d / hashlib.sha1(data).hexdigest()).write_bytes(data)


def toml_blocks(md: Path) -> list[str]:
    return re.findall(r"```toml\n(.*?)```", md.read_text(), re.S)


def byte_literals(path: Path) -> list[bytes]:
    text = path.read_text()
    out = []
    for m in re.finditer(r'b"((?:[^"\\]|\\.)*)"', text):
        try:
            out.append(ast.literal_eval('b"' + m.group(1) + '"'))
        except (ValueError, SyntaxError):
            pass
    for m in re.finditer(r"\[\s*((?:0x[0-9A-Fa-f]{1,2}\s*,\s*){3,}0x[0-9A-Fa-f]{1,2})\s*,?\s*\]", text):
        out.append(bytes(int(x, 16) for x in re.findall(r"0x[0-9A-Fa-f]+", m.group(1))))
    return out


def small_recordings() -> list[bytes]:
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, Writer

    src = (ROOT / "recordings" / "demo-null.mcap").read_bytes()
    outs = []
    for keep, compression in ((4, CompressionType.NONE), (12, CompressionType.ZSTD)):
        reader = make_reader(io.BytesIO(src))
        buf = io.BytesIO()
        w = Writer(buf, compression=compression)
        w.start(profile="", library="seed_corpora.py")
        schemas, channels, counts = {}, {}, {}
        for schema, channel, msg in reader.iter_messages(log_time_order=False):
            if counts.get(channel.topic, 0) >= keep:
                continue
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], dict(channel.metadata)
                )
            w.add_message(channels[channel.id], msg.log_time, msg.data, msg.publish_time, msg.sequence)
        for md in reader.iter_metadata():
            w.add_metadata(md.name, dict(md.metadata))
        w.finish()
        outs.append(buf.getvalue())
    return outs


def main() -> None:
    docs = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]
    blocks = [b for md in docs for b in toml_blocks(md)]
    for f in sorted((ROOT / "scenarios").glob("*.toml")):
        put("scenario", f.read_bytes())
    for b in blocks:
        if "[[step]]" in b or "[scenario]" in b:
            put("scenario", b.encode())
        elif "[gyro_model]" in b:
            put("calibration_file", b.encode())
        else:
            put("bench_config", b.encode())
    for f in sorted((ROOT / "scenarios" / "models").glob("*.toml")):
        put("calibration_file", f.read_bytes())
    for f in sorted((ROOT / "tests" / "fixtures" / "lab").rglob("*.toml")):
        put("bench_config", f.read_bytes())
    protocol = {
        "actidyn": ["drivers/src/protocol/actidyn.rs", "drivers/tests/it/protocol_table.rs"],
        "acutrol": ["drivers/src/protocol/acutrol.rs", "drivers/tests/it/protocol_table.rs"],
        "kvh1750": ["drivers/tests/it/protocol_kvh1750.rs"],
        "kvh_dsp3000": ["drivers/src/protocol/kvh_dsp3000.rs", "drivers/tests/it/protocol_kvh_dsp3000.rs"],
        "slcan": ["drivers/src/protocol/slcan.rs", "drivers/tests/it/protocol_slcan.rs"],
        "gyro_can": ["drivers/tests/it/protocol_slcan.rs", "drivers/src/real/slcan.rs"],
        "modbus_map": ["drivers/tests/it/protocol_modbus_map.rs"],
    }
    for target, files in protocol.items():
        for f in files:
            p = ROOT / f
            if p.exists():
                for b in byte_literals(p):
                    if b:
                        put(target, b)
    recs = small_recordings() + [p.read_bytes() for p in sorted((ROOT / "tests" / "fixtures").glob("*.mcap"))]
    for r in recs:
        for target in ("recording", "recover", "run_data"):
            put(target, r)
    # The recordings' model metadata, as the model_metadata target reads it.
    from mcap.reader import make_reader

    reader = make_reader(io.BytesIO((ROOT / "recordings" / "demo-null.mcap").read_bytes()))
    for md in reader.iter_metadata():
        if md.name == "bench.gyro_model":
            put("model_metadata", "".join(f"{k}={v}\n" for k, v in md.metadata.items()).encode())
    # The unbroken and broken TOML inputs of scripts/bad_inputs.py.
    import sys

    sys.path.insert(0, str(ROOT / "scripts"))
    import bad_inputs

    put("scenario", bad_inputs.SCENARIO.encode())
    put("bench_config", bad_inputs.CONFIG.encode())
    put("calibration_file", bad_inputs.MODEL.encode())
    for target, cases in (
        ("scenario", bad_inputs.scenarios()),
        ("bench_config", bad_inputs.configs()),
        ("calibration_file", bad_inputs.models()),
    ):
        for _, data in cases:
            if len(data) < 20_000:
                put(target, data)
    for d in sorted(OUT.iterdir()):
        print(f"{d.name:18} {len(list(d.iterdir())):4} seeds")


if __name__ == "__main__":
    main()
