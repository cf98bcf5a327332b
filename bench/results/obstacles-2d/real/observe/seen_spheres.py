"""Which spheres a policy touches on obstacles-2d-clock-one-leg, and whether the observation
showed each at the moment of its first touch (the nearest one ahead of the pelvis is all
it shows). Session 28's diagnostic, kept with its result (seen-60min.json).

Usage: python seen_spheres.py CHECKPOINT FIRST_SEED EPISODES OUT.json
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import torch
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluate import fitted_to_scene
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene


def first_touches(env: MuscleEnv, policy, seed: int) -> dict:
    """One deterministic episode: each sphere's first touch (time s, whether it was the one
    observed, its rank among the spheres ahead, -1 if passed, and the foot geom)."""
    sim, model = env.sim, env.sim.model
    ids = sim._obstacle_ids.tolist()
    obs, _ = env.reset(seed=seed)
    touched: dict[int, dict] = {}
    for k in range(env.scene.steps_per_episode):
        spheres = sim.obstacles()
        here = float(sim.state().pelvis_pos[sim.forward_axis])
        ahead = np.where(spheres[:, 0] + spheres[:, 2] > here)[0]
        seen = int(ahead[np.argmin(spheres[ahead, 0])]) if len(ahead) else -1
        with torch.no_grad():
            action = policy.mean_action(torch.as_tensor(obs[None], dtype=torch.float32))[0]
        obs, _, terminated, truncated, _ = env.step(action.numpy())
        for contact in sim.data.contact[: sim.data.ncon]:
            for geom, other in ((contact.geom1, contact.geom2), (contact.geom2, contact.geom1)):
                j = ids.index(geom) if geom in ids else None
                if j is None or j in touched:
                    continue
                rank = int(np.sum(spheres[ahead, 0] < spheres[j, 0])) if j in ahead else -1
                touched[j] = {
                    "t": round((k + 1) * env.dt, 2),
                    "seen": j == seen,
                    "rank": rank,
                    "dx": round(float(spheres[j, 0] - here), 2),
                    "foot": mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, other),
                }
        if terminated or truncated:
            break
    return {
        "seed": seed,
        "fell": bool(terminated and not truncated),
        "touches": list(touched.values()),
    }


def main() -> None:
    checkpoint, first, episodes, out = (
        Path(sys.argv[1]),
        int(sys.argv[2]),
        int(sys.argv[3]),
        sys.argv[4],
    )
    scene = load_scene("obstacles-2d-clock-one-leg").resolved()
    policy, meta = load_policy(checkpoint)
    policy, _ = fitted_to_scene(policy, meta.obs_names, scene, "mujoco")
    env = MuscleEnv(scene)
    rows = [first_touches(env, policy, seed) for seed in range(first, first + episodes)]
    Path(out).write_text(json.dumps(rows, indent=0))
    touches = [t for r in rows for t in r["touches"]]
    ranks = sorted({t["rank"] for t in touches})
    print("episodes", len(rows), "falls", sum(r["fell"] for r in rows), "touches", len(touches))
    print(
        "seen",
        sum(t["seen"] for t in touches),
        "by rank (-1: passed)",
        {k: sum(t["rank"] == k for t in touches) for k in ranks},
    )
    last = [max(r["touches"], key=lambda t: t["t"]) for r in rows if r["fell"] and r["touches"]]
    print("falls after a touch", len(last), "the last touch seen", sum(t["seen"] for t in last))


if __name__ == "__main__":
    main()
