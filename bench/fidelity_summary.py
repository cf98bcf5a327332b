"""Markdown tables for the README from the fidelity sweeps' JSON files.

Usage: python bench/fidelity_summary.py [DIR]   (default bench/results/fidelity)

Per sweep: the reference and its convergence margin, the Pareto-optimal stable profiles
(no other stable profile is both faster and more accurate), the unstable ones, the model
differences, and the recommended profile. Then the speed-ups over the 2017 challenge's
setting (OpenSim, RK-Merson, accuracy 5e-5), within OpenSim and across simulators.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def _f(x: object, fmt: str = ".3g") -> str:
    return x if isinstance(x, str) else format(x, fmt)


def pareto(rows: list[dict]) -> list[dict]:
    stable = [r for r in rows if r["stable"]]
    return sorted(
        (
            r
            for r in stable
            if not any(
                o["steps_per_s"] > r["steps_per_s"] and _num(o["error"]) < _num(r["error"])
                for o in stable
            )
        ),
        key=lambda r: -r["steps_per_s"],
    )


def _num(x: object) -> float:
    return float(x) if not isinstance(x, str) else float("inf")


def sweep_table(data: dict) -> str:
    ref = data["reference"]
    out = [
        f"### `{data['scene']}` on {data['backend']}",
        "",
        f"Reference {ref['profile']}; refined to {ref['refined']} it changes by "
        f"{ref['refined_change']:.2g} rad RMS: margin **{ref['margin']:.0f}x** the tolerance "
        f"{data['tolerance']:g} rad (needs {ref['required_margin']:g}x). Reference speed "
        f"{ref['steps_per_s']:.0f} env steps/s.",
        "",
        f"| profile | env steps/s | real-time x | error {data['size']['short']:g} s (rad) "
        f"| error {data['size']['long']:g} s (rad) | distance vs reference (m, 95% CI) | "
        "falls | within |",
        "|---|---|---|---|---|---|---|---|",
    ]
    shown = pareto(data["rows"])
    challenge = [r for r in data["rows"] if r["label"] == "rk-merson acc 5e-05"]
    for r in shown + [c for c in challenge if c not in shown]:
        t = r["task"]
        name = r["label"] + (" (2017 challenge)" if r["label"] == "rk-merson acc 5e-05" else "")
        if data["recommended"] and r["label"] == data["recommended"]["label"]:
            name = f"**{name} (recommended)**"
        out.append(
            f"| {name} | {r['steps_per_s']:.0f} | {r['realtime']:.2f} | {_f(r['err_short'])} | "
            f"{_f(r['err_long'])} | {t['distance_vs_ref']:+.3f} ± {t['distance_vs_ref_ci']:.3f} "
            f"| {t['fall_rate']:.2f} | {'yes' if r['within'] else 'no'} |"
        )
    bad = [r for r in data["rows"] if not r["stable"]]
    out.append("")
    unstable = ", ".join(f"{r['label']} ({r['health']})" for r in bad) or "none"
    out.append(
        f"Pareto-optimal stable profiles shown; {len(data['rows'])} measured. Unstable: {unstable}."
    )
    if data["model"]:
        head = "| model difference | setting | RMS 0.5 s (rad) | RMS 2 s (rad) | speed ratio |"
        out += ["", head, "|---|---|---|---|---|"]
        for m in data["model"]:
            out.append(
                f"| {m['what']} | {m['setting']} | {_f(m['rms_short'])} | "
                f"{_f(m['rms_long'])} | {m['speed_ratio']:.2f} |"
            )
    return "\n".join(out)


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "bench/results/fidelity")
    sweeps = {p.stem: json.loads(p.read_text()) for p in sorted(root.glob("*.json"))}
    for data in sweeps.values():
        print(sweep_table(data), end="\n\n")
    osim = sweeps.get("walk-2d-opensim")
    if osim and osim.get("challenge"):
        c = osim["challenge"]
        print(
            f"- OpenSim: {c['recommended']} runs {c['recommended_steps_per_s']:.0f} env steps/s "
            f"at error {c['recommended_error']:.2g} rad against {c['challenge_steps_per_s']:.0f} "
            f"for the 2017 setting ({c['challenge']}, error {c['challenge_error']:.2g} rad): "
            f"**{c['speedup']:.1f}x**."
        )
        for name in ("walk-2d-mujoco",):
            mj = sweeps.get(name)
            if mj and mj["recommended"]:
                r = mj["recommended"]
                model = next((m for m in mj["model"] if m["what"].startswith("opensim")), None)
                gap = f"; the simulators differ by {_f(model['rms_long'])} rad" if model else ""
                print(
                    f"- MuJoCo: {r['label']} runs {r['steps_per_s']:.0f} env steps/s at error "
                    f"{_f(r['error'])} rad against its own reference: "
                    f"**{r['steps_per_s'] / c['challenge_steps_per_s']:.0f}x** the 2017 "
                    f"setting on OpenSim{gap} (model error, not integration error)."
                )


if __name__ == "__main__":
    main()
