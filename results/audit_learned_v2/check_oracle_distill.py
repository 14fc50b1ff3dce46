"""Audit (point 5): the --teacher oracle distillation on RunUpRandomized-v2, tiny, on the NATIVE vector env
(the training default; the repo's label test uses "dummy"):
 (a) OracleTeacher's labels == CommandedOracle's actions on the native env's own env objects across
     autoresets (plan read right after SB3-style same-step autoreset);
 (b) distill() itself: every (x, y) row of the first iteration is the normalised observation history and
     the oracle label of the SAME step (independent replay with the same TRAIN env seed), across autoresets;
 (c) the deployed student: DeployedActor input = history x n_obs, statistics = mean/var of observations."""
import json, pickle, shutil
from pathlib import Path
import numpy as np, yaml
import gfb_env.envs  # noqa
from gfb_agents import seeds
from gfb_agents.learned import teacher_student as ts
from gfb_agents.learned.oracle_teacher import OracleTeacher
from gfb_agents.learned.train import load_hyperparams, make_vec_env_for
from gfb_agents.learned.vec_env import DampingSlewVecEnv, PrivilegedVecEnv
from gfb_agents.learned.evaluate import LearnedPolicy
from gfb_agents.learned.asymmetric import DeployedActor
from gfb_agents.oracles.commanded import CommandedOracle

ENV = "gfb_env/RunUpRandomized-v2"
KW = {"max_episode_steps": 5}
T = Path("/work/audit_learned/tmp")

# (a)
n = 2
venv = make_vec_env_for(ENV, n, 1_777_000, None, KW, "native")
inner = venv.venv  # VecMonitor -> GFBSB3VecEnv
teacher = OracleTeacher(ENV, n)
refs = [CommandedOracle(e) for e in inner.venv.envs]
o = venv.reset(); starts = np.ones(n, bool); worst = 0.0; plans = set()
for k in range(13):
    if starts.any():
        teacher.plan_episodes(venv, np.flatnonzero(starts))
    lab = teacher.act(o, None, starts)
    for i, ref in enumerate(refs):
        if starts[i]:
            ref.reset()
        want, _ = ref.predict(o[i], episode_start=np.array([starts[i]]))
        worst = max(worst, float(np.max(np.abs(lab[i] - want))))
        plans.add(round(float(teacher.plan[i, 0]), 9))
    o, _, d, _ = venv.step(lab); starts = np.asarray(d, bool)
print(f"(a) native vec env: max |label - CommandedOracle| over 13 steps x 2 envs (2 autoresets each): {worst:.2e}; distinct plans {len(plans)}")
venv.close()

# (b)
hs = load_hyperparams("teacher_student", ENV)
hs.update(n_envs=2, steps_per_iteration=16, epochs=1, batch_size=8, history=3, hidden=[8])
hp = T / "hp.yml"; hp.write_text(yaml.safe_dump({ENV: hs}))
out = T / "distill"
shutil.rmtree(out, ignore_errors=True)
cfg = ts.DistillConfig(teacher="oracle", env_id=ENV, env_kwargs=KW, damping_slew=0.027, timesteps=32,
                       out=out, hyperparams=hp, eval_episodes=1)
ts.distill(cfg)
data = np.load(out / "checkpoints" / "iter_00002" / "data.npz")
X, Y = data["x"], data["y"]
with open(out / "vecnormalize.pkl", "rb") as fh:
    vn = pickle.load(fh)
mean, var = vn.obs_rms.mean, vn.obs_rms.var
# independent replay of iteration 1 (teacher alone): same env seed, same wrappers
base = DampingSlewVecEnv(make_vec_env_for(ENV, 2, seeds.train_env_seed(0, 0, 0), None, KW, "native"), 0.027)
pv = PrivilegedVecEnv(base)
t2 = OracleTeacher(ENV, 2)
o = pv.reset(); starts = np.ones(2, bool); raws, labels, st = [], [], []
for _ in range(8):
    if starts.any():
        t2.plan_episodes(pv, np.flatnonzero(starts))
    lab = t2.act(o["obs"], o["privileged"], starts)
    raws.append(o["obs"].copy()); labels.append(lab.copy()); st.append(starts.copy())
    o, _, d, _ = pv.step(lab); starts = np.asarray(d, bool)
raw = np.concatenate(raws)
print("(b) statistics == mean/var of the replayed observations:",
      np.allclose(mean, raw.mean(0), rtol=1e-6, atol=1e-9), np.allclose(var, raw.var(0), rtol=1e-5, atol=1e-12),
      "| privileged dim in the pickle:", isinstance(vn.obs_rms, dict))
stack = ts._Stack(3)
xs = np.concatenate([stack(ts._normalise(r, mean, var, 1e-8, 10.0), s) for r, s in zip(raws, st)])
ys = np.concatenate([np.clip(l, -1, 1) for l in labels])
print(f"(b) iteration-1 rows: {len(xs)}; X rows equal replayed history: {np.allclose(X[:16], xs, atol=1e-6)}; "
      f"Y rows equal the same step's oracle label: {np.allclose(Y[:16], ys, atol=1e-7)}; "
      f"label shifted by one step would match: {np.allclose(Y[1:16], ys[:-1], atol=1e-7)}; "
      f"episode starts in replay: {int(np.concatenate(st).sum())}")
# (c)
pol = LearnedPolicy(out)
print(f"(c) deployed: {type(pol.model).__name__} obs_dim {pol.model.obs_dim} = 3 x {raw.shape[1]}; "
      f"stats dims {pol.obs_mean.shape}; reads env? {hasattr(pol, 'env')}; has observe_reset_info? {hasattr(pol, 'observe_reset_info')}")
print("run.json:", {k: json.loads((out / 'run.json').read_text()).get(k) for k in ('teacher_kind', 'damping_slew', 'frame_stack', 'validation_seeds')})
