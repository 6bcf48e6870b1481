#!/usr/bin/env bash
# What only the installed wheel can get wrong, checked from a folder outside the checkout:
# the entry point, each command run once on a shipped sample (package data: profiles, the
# report's assets, the capture formats' registry), and each output read back by its own reader.
# Usage: wheel_commands.sh VENV SAMPLES_DIR
set -euo pipefail
venv="$1"
samples="$2"
bin="$venv/bin"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
cp "$samples"/atv71-plc-poll.log "$samples"/atv71-plc-poll.mcap "$samples"/xbt-hmi.log "$samples"/xbt-floats.log .

ran=0
failed=0
check() {  # check NAME COMMAND...: runs COMMAND, which must exit 0
  local name="$1"
  shift
  if "$@" >"$work/out.txt" 2>"$work/err.txt"; then
    ran=$((ran + 1))
  else
    failed=$((failed + 1))
    echo "ci: wheel: $name failed: $*" >&2
    tail -5 "$work/err.txt" >&2
  fi
}

"$bin/python" - <<'PY'
import sys
import decoders, sniffer
for package in (sniffer, decoders):
    if "site-packages" not in package.__file__:
        sys.exit(f"ci: {package.__name__} comes from {package.__file__}, not the installed wheel")
PY
check "version" "$bin/rtusniff" --version
check "python -m sniffer" "$bin/python" -m sniffer --version
check "analyze" "$bin/rtusniff" analyze atv71-plc-poll.log
check "analyze jsonl" "$bin/rtusniff" analyze atv71-plc-poll.mcap --format jsonl -o frames.jsonl
check "stats" "$bin/rtusniff" stats atv71-plc-poll.log --format json -o stats.json
check "values" "$bin/rtusniff" values atv71-plc-poll.log -o values.csv
check "report html" "$bin/rtusniff" report atv71-plc-poll.log -o report.html
check "report md" "$bin/rtusniff" report xbt-hmi.log -o report.md
check "compare" "$bin/rtusniff" compare atv71-plc-poll.log xbt-hmi.log
check "cut" "$bin/rtusniff" cut atv71-plc-poll.log --around 10 --context 3 -o cut.log
check "convert" "$bin/rtusniff" convert xbt-hmi.log xbt.mcap
check "export" "$bin/rtusniff" export atv71-plc-poll.log --mcap out.mcap --rrd out.rrd --pcap out.pcapng \
  --parquet dataset -q
check "profiles list" "$bin/rtusniff" profiles list
check "profiles show" "$bin/rtusniff" profiles show atv71
check "profiles draft" "$bin/rtusniff" profiles draft xbt-floats.log --slave 54 -o draft.toml
check "profiles check" "$bin/rtusniff" profiles check draft.toml
printf 'Address,Name,Type,Word order\n40031,Tank level,REAL,CDAB\n' >map.csv
check "profiles import" "$bin/rtusniff" profiles import map.csv -o map.toml
check "typed registers" "$bin/rtusniff" values xbt-floats.log --profile-file map.toml --profile 54=map \
  --registers f32:little -o floats.csv
# The library from the wheel: a table made as the export made it, py.typed shipped.
check "library" "$bin/python" -c "import sniffer, importlib.resources as r; \
t = sniffer.open_capture('atv71-plc-poll.log', profile='atv71').table('frames'); assert t.num_rows == 52, t.num_rows; \
assert r.files('sniffer').joinpath('py.typed').is_file()"
check "ports" "$bin/rtusniff" ports
check "capture --help" "$bin/rtusniff" capture --help
check "wireshark setup" "$bin/rtusniff" wireshark setup --config-dir ws-config --extcap-dir ws-extcap
check "wireshark extcap" ws-extcap/rtusniff-extcap --extcap-interfaces --extcap-version=4.0
# The outputs read back: the report carries its script, the exports open in their readers.
check "outputs read back" "$bin/python" - <<'PY'
import json
from pathlib import Path

import pyarrow.parquet as pq
from mcap.reader import make_reader

assert "<script" in Path("report.html").read_text(), "the HTML report lacks its inline script"
assert json.loads(Path("stats.json").read_text())["frames"] > 0
with open("out.mcap", "rb") as stream:
    assert sum(1 for _ in make_reader(stream).iter_messages()) > 0
assert pq.read_table("dataset").num_rows > 0
assert sum(1 for _ in open("frames.jsonl")) > 52
assert Path("out.rrd").stat().st_size > 0 and Path("out.pcapng").stat().st_size > 0
PY
# A wrong option and a broken file: one error line and the documented exit codes.
set +e
"$bin/rtusniff" analyze atv71-plc-poll.log --no-such-option >/dev/null 2>&1
[ $? -eq 2 ] || { echo "ci: wheel: a wrong option does not exit 2" >&2; failed=$((failed + 1)); }
"$bin/rtusniff" analyze missing.log >/dev/null 2>&1
[ $? -eq 3 ] || { echo "ci: wheel: a missing file does not exit 3" >&2; failed=$((failed + 1)); }
set -e
echo "ci: the wheel's commands: $ran ran, $failed failed"
[ "$failed" -eq 0 ]
