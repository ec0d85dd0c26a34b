"""The twin table of docs/explanation/optimisers.md from the JSON of ``rivercal bench calibrate``.

Usage: ``rivercal bench calibrate --json | python docs/tools/twin_table.py > docs/explanation/optimisers-twin.md``.
The benchmark takes minutes (every optimiser on the default case), too long to run at each build of the
site; its table is regenerated with this command when an optimiser changes.
"""

from __future__ import annotations

import json
import sys


def table(bench: dict) -> str:
    """Markdown: one row per algorithm (runs, estimates, errors, cost); wall times are left out (machine-dependent)."""
    truth = bench["truth"]
    lines = [
        "| method | model runs | k_s (m^(1/3)/s) | Wc (-) | error k_s | error Wc | cost S |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in bench["results"]:
        lines.append(f"| `{r['algorithm']}` | {r['model_runs']} | {r['fa']:.4f} | {r['wc']:.4f} | "
                     f"{r['error_fa']:.1e} | {r['error_wc']:.1e} | {r['cost']:.2g} |")
    lines.append("")
    lines.append(f"Truth k_s = {truth['FA']:g}, Wc = {truth['Wc']:g}; {bench['observations']} observations; "
                 "cost S of thesis Eq. 2-3 with σ = 2.5 cm on levels and 0.1 m³/s on discharges (noise-free data: "
                 "S = 0 at the truth).")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(table(json.loads(sys.stdin.read())))
