#!/usr/bin/env bash
# `drltg demo`, timed, kept in results/demo/ with its report and the machine it ran on (machine.json):
#   bash results/demo.sh "a shared 2-core AMD EPYC virtual machine (CPU only, torch 2.13.0)"
# From a fresh clone, time the install and pass it on (INSTALL_NOTE says how it was installed):
#   /usr/bin/time -f %e -o install.txt make install && INSTALL_S=$(cat install.txt) bash results/demo.sh "..."
set -euo pipefail
cd "$(dirname "$0")/.."
machine=${1:?describe the machine in a few words}
rm -rf runs/demo && mkdir -p runs
load_before=$(cut -d' ' -f1 /proc/loadavg)
/usr/bin/time -f '%e %U %S' -o runs/demo-time.txt drltg demo --out runs/demo
load_after=$(cut -d' ' -f1 /proc/loadavg)
rm -rf results/demo
python - "$machine" "$load_before" "$load_after" "${INSTALL_S:-}" "${INSTALL_NOTE:-}" <<'PY'
import json, os, sys
from pathlib import Path
sys.path.insert(0, "results")
from rebuild import keep_curves
from drltg.report import transfer_report
from drltg.cli.demo import DEMO
from drltg.store import rundir

machine, before, after, install, note = sys.argv[1:]
dest = Path("results/demo")
keep_curves(Path("runs/demo").resolve(), dest.resolve())
rundir.atomic_write(dest / "demo.yaml", Path("runs/demo/demo.yaml").read_text())
transfer_report(dest / "baseline", dest / "transfer", dest / "report", threshold=DEMO["threshold"],
                baseline_label="no transfer", transfer_label=DEMO["method"])
(dest / "report" / "transfer_plot.svg").unlink()
wall, user, system = map(float, Path("runs/demo-time.txt").read_text().split()[-3:])
low, high = sorted([float(before), float(after)])
rundir.atomic_write(dest / "machine.json", json.dumps({
    "machine": machine, "cores": os.cpu_count(), "command": "time drltg demo --out runs/demo (venv installed)",
    "wall_s": wall, "cpu_s": user + system, "load": f"{low:.1f} to {high:.1f}",
    **({"install_s": float(install),
        "install": "`make install` from a fresh clone" + (f" ({note})" if note else "")} if install else {})},
    indent=2) + "\n")
PY
python results/claims.py
