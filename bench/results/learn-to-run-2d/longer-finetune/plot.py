"""The longer run stage's falls against env steps: the in-training evaluations (100 episodes,
seeds 1,000,000 + i, from seed-S.log) as lines, the 200-episode judgements on seeds 0-199
(evaluated-200/seed-S-<env steps>.txt) as dots, each seed's start (its recipe run's end
network, judged the same way) at 0.

python bench/results/learn-to-run-2d/longer-finetune/plot.py  ->  longer-finetune.png
"""

import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

HERE = Path(__file__).parent
# the starts on 200 episodes, seeds 0-199 (README "Learning to run", sessions 16-17)
START_FALLS = {0: 0.11, 2: 0.10}
EVALUATED = re.compile(r"([\d,]+) env steps \(.*evaluated: .* falls (\d+) %")


def main() -> None:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for seed, color in ((0, "tab:blue"), (2, "tab:orange")):
        points = [
            (int(m[1].replace(",", "")), int(m[2]) / 100)
            for m in map(EVALUATED.search, (HERE / f"seed-{seed}.log").read_text().splitlines())
            if m
        ]
        ax.plot(
            *zip(*points, strict=True),
            color=color,
            label=f"seed {seed}, in training (100 episodes)",
        )
        judged = [(0, START_FALLS[seed])]
        for path in sorted((HERE / "evaluated-200").glob(f"seed-{seed}-*.txt")):
            falls = re.search(r"fall rate\s*│\s*(\d+) %", path.read_text())
            judged.append((int(path.stem.rsplit("-", 1)[1]), int(falls[1]) / 100))
        ax.plot(
            *zip(*judged, strict=True), "o", color=color, label=f"seed {seed}, 200 other episodes"
        )
    ax.axhline(0.1, color="grey", ls="--", lw=1)
    ax.set_xlabel("env steps continued (from 0.4 M of the run stage: seed 0; 0.6 M: seed 2)")
    ax.set_ylabel("falls, run-2d-clock, deterministic")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "longer-finetune.png", dpi=100)


if __name__ == "__main__":
    main()
