"""For each first touch of a sphere: was it the sphere the observation showed at that moment?"""
import sys, json
import numpy as np, torch, mujoco
from pathlib import Path
from gaitforge.learner.checkpoint import load_policy
from gaitforge.learner.evaluate import fitted_to_scene
from gaitforge.workers.env import MuscleEnv
from gaitforge.workers.scenes import load_scene

ckpt, first, n = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
scene = load_scene("obstacles-2d-clock-one-leg").resolved()
policy, meta = load_policy(ckpt)
policy, names = fitted_to_scene(policy, meta.obs_names, scene, "mujoco")
env = MuscleEnv(scene); sim = env.sim; m = sim.model
ids = sim._obstacle_ids.tolist()
rows = []
for seed in range(first, first + n):
    obs, _ = env.reset(seed=seed)
    touched = {}
    for k in range(scene.steps_per_episode):
        o = sim.obstacles()
        here = float(sim.state().pelvis_pos[sim.forward_axis])
        ahead = np.where(o[:, 0] + o[:, 2] > here)[0]
        seen = int(ahead[np.argmin(o[ahead, 0])]) if len(ahead) else -1
        with torch.no_grad():
            a = policy.mean_action(torch.as_tensor(obs[None], dtype=torch.float32))[0].numpy()
        obs, r, term, trunc, info = env.step(a)
        d = sim.data
        for c in d.contact[: d.ncon]:
            for g, other in ((c.geom1, c.geom2), (c.geom2, c.geom1)):
                if g in ids and ids.index(g) not in touched:
                    j = ids.index(g)
                    rank = int(np.sum(o[ahead, 0] < o[j, 0])) if j in ahead else -1
                    touched[j] = dict(t=round((k + 1) * env.dt, 2), seen=(j == seen), rank=rank,
                                      dx=round(float(o[j, 0] - here), 2), r=round(float(o[j, 2]), 3),
                                      h=round(float(o[j, 1]), 3),
                                      foot=mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, other))
        if term or trunc:
            break
    fell = bool(term and not trunc)
    rows.append(dict(seed=seed, fell=fell, t_end=round((k + 1) * env.dt, 2), touches=list(touched.values())))
json.dump(rows, open(sys.argv[4], "w"), indent=0)
T = [t for r in rows for t in r["touches"]]
print("episodes", len(rows), "falls", sum(r["fell"] for r in rows), "touches", len(T))
print("seen", sum(t["seen"] for t in T), "rank(ahead order; -1 behind pelvis)",
      {k: sum(t["rank"] == k for t in T) for k in sorted({t["rank"] for t in T})})
# the last touch before each fall
last = [max(r["touches"], key=lambda t: t["t"]) for r in rows if r["fell"] and r["touches"]]
print("falls' last touch: seen", sum(t["seen"] for t in last), "of", len(last),
      {k: sum(t["rank"] == k for t in last) for k in sorted({t["rank"] for t in last})})
print("dx at touch", np.percentile([t["dx"] for t in T], [10, 50, 90]))
