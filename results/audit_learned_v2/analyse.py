"""Audit analysis: (1) recompute the committed table's RunUpRandomized-v2 learned-vs-rule numbers from
results/benchmark_agents.json; (2) my hidden-seed episodes (episodes.jsonl): per-seed returns, paired
differences vs margin_aim_1x_05, normalised IQM/mean on (a) my own seeds' hold/oracle scale and (b) the
test table's fixed scale; (3) damping-command slew."""
import json, math
from collections import defaultdict
from pathlib import Path
import numpy as np
from gfb_experiments.benchmark_stats import iqm, normalized_scores, paired_headroom, interval_estimates

TASK = "gfb_env/RunUpRandomized-v2"
RULE = "margin_aim_1x_05"
A = Path("/work/audit_learned")
rep = []
def p(*a):
    s = " ".join(str(x) for x in a); print(s); rep.append(s)

# ---- (1) the committed table
b = json.load(open("/work/main/results/benchmark_agents.json"))["tasks"][TASK]
ag = b["agents"]
sc = b["scales"]
p("## (1) committed table, recomputed from results/benchmark_agents.json")
p(f"scale: IQM zero {sc['iqm']['reference_zero']:.3f} gap {sc['iqm']['reference_gap']:.3f}; mean zero {sc['mean']['reference_zero']:.3f} gap {sc['mean']['reference_gap']:.3f}")
for name in (RULE, "RunUpRandomized-v2_ppo_fs4", "RunUpRandomized-v2_student", "RunUpRandomized-v2_sac"):
    r = np.array(ag[name]["returns"])
    niqm = (iqm(r) - sc["iqm"]["reference_zero"]) / sc["iqm"]["reference_gap"]
    nmean = (r.mean() - sc["mean"]["reference_zero"]) / sc["mean"]["reference_gap"]
    per_run = [round((iqm(x) - sc["iqm"]["reference_zero"]) / sc["iqm"]["reference_gap"], 3) for x in r]
    line = f"{name}: runs {r.shape[0]} normalised IQM {niqm:.3f} mean {nmean:.3f} per-run IQM {per_run}"
    if name != RULE:
        h = paired_headroom(np.array(ag[name]["normalized"]), np.array(ag[RULE]["normalized"]), reps=2000,
                            oracle_mean=np.array(ag[name]["normalized_mean"]), rule_mean=np.array(ag[RULE]["normalized_mean"]))
        line += f" | minus rule: {json.dumps({k: round(v, 3) for k, v in h.items() if isinstance(v, float)})}"
    p(line)

# ---- (2) hidden seeds
eps = defaultdict(dict)
for l in open(A / "episodes.jsonl"):
    d = json.loads(l)
    eps[d["agent"]][d["seed"]] = d
import os
seeds = sorted(set.intersection(*[set(v) for v in eps.values()]))[: int(os.environ.get("N", "1000"))]
p(f"\n## (2) hidden seeds {seeds[0]}..{seeds[-1]} (n = {len(seeds)}; every agent played every seed)")
R = {a: np.array([eps[a][s]["episode_return"] for s in seeds]) for a in eps}
def group(prefix):
    return [a for a in eps if a.startswith(prefix)]
groups = {"ppo": group("RunUpRandomized-v2_ppo_fs4"), "student": group("RunUpRandomized-v2_student"),
          "sac": group("RunUpRandomized-v2_sac")}
# per-seed table
hdr = ["seed", "naive", "hold", "oracle_v1", RULE, "ppo/seed2", "student/seed0", "sac/seed0",
       "ppo(5 mean)", "student(5 mean)", "sac(4 mean)"]
rows = []
for i, s in enumerate(seeds):
    rows.append([s, R["naive"][i], R["hold"][i], R["oracle_v1"][i], R[RULE][i],
                 R["RunUpRandomized-v2_ppo_fs4/seed2"][i], R["RunUpRandomized-v2_student/seed0"][i],
                 R["RunUpRandomized-v2_sac/seed0"][i]] +
                [np.mean([R[a][i] for a in groups[g]]) for g in ("ppo", "student", "sac")])
p("| " + " | ".join(hdr) + " |"); p("|" + "---|" * len(hdr))
for r in rows:
    p("| " + " | ".join([str(r[0])] + [f"{x:.1f}" for x in r[1:]]) + " |")
p("| mean | " + " | ".join(f"{np.mean([r[j] for r in rows]):.1f}" for j in range(1, len(hdr))) + " |")

def norm_block(label, zero_iqm, gap_iqm, zero_mean, gap_mean):
    p(f"\n### normalised on {label}: IQM scale zero {zero_iqm:.2f} gap {gap_iqm:.2f}; mean scale zero {zero_mean:.2f} gap {gap_mean:.2f}")
    rule_i = (R[RULE] - zero_iqm) / gap_iqm
    rule_m = (R[RULE] - zero_mean) / gap_mean
    p(f"{RULE}: IQM {iqm(rule_i):.3f} mean {rule_m.mean():.3f}")
    for pick in ("RunUpRandomized-v2_ppo_fs4/seed2", "RunUpRandomized-v2_student/seed0", "RunUpRandomized-v2_sac/seed0"):
        si, sm = (R[pick] - zero_iqm) / gap_iqm, (R[pick] - zero_mean) / gap_mean
        h = paired_headroom(si, rule_i, reps=5000, oracle_mean=sm, rule_mean=rule_m)
        p(f"{pick}: IQM {iqm(si):.3f} mean {sm.mean():.3f} | minus rule IQM {h['iqm']:.3f} "
          f"[{h['iqm_low']:.3f}, {h['iqm_high']:.3f}] mean {h['mean']:.3f} [{h['mean_low']:.3f}, {h['mean_high']:.3f}]"
          if "iqm" in h else f"{pick}: {h}")
    for g, names in groups.items():
        M = np.array([R[a] for a in names])
        si, sm = (M - zero_iqm) / gap_iqm, (M - zero_mean) / gap_mean
        h = paired_headroom(si, rule_i, reps=5000, oracle_mean=sm, rule_mean=rule_m)
        p(f"{g} (all {len(names)} runs): IQM {iqm(si):.3f} mean {sm.mean():.3f} | minus rule " +
          json.dumps({k: round(v, 3) for k, v in h.items() if isinstance(v, float)}))

zi, gi = iqm(R["hold"]), iqm(R["oracle_v1"]) - iqm(R["hold"])
zm, gm = R["hold"].mean(), R["oracle_v1"].mean() - R["hold"].mean()
# the project's reference choice: the better of naive and hold per statistic
if iqm(R["naive"]) > iqm(R["hold"]): zi, gi = iqm(R["naive"]), iqm(R["oracle_v1"]) - iqm(R["naive"])
if R["naive"].mean() > R["hold"].mean(): zm, gm = R["naive"].mean(), R["oracle_v1"].mean() - R["naive"].mean()
norm_block("MY seeds' own references (better of naive/hold; oracle_v1)", zi, gi, zm, gm)
norm_block("the TEST table's fixed scale", sc["iqm"]["reference_zero"], sc["iqm"]["reference_gap"],
           sc["mean"]["reference_zero"], sc["mean"]["reference_gap"])

# paired raw differences per seed (learned - rule)
p("\n### paired raw return differences (learned - rule) per seed")
for pick in ("RunUpRandomized-v2_ppo_fs4/seed2", "RunUpRandomized-v2_student/seed0"):
    d = R[pick] - R[RULE]
    se = d.std(ddof=1) / math.sqrt(len(d))
    p(f"{pick}: {[round(x, 1) for x in d]} | mean {d.mean():.2f} (SE {se:.2f}), learned better on {int((d > 0).sum())}/{len(d)} seeds")
    d12 = d[:12]
    p(f"   first 12 seeds only: mean {d12.mean():.2f} (SE {d12.std(ddof=1) / math.sqrt(12):.2f}), learned better on {int((d12 > 0).sum())}/12")

# outcomes
p("\n### outcomes (success / touchdown counts)")
for a in ["naive", "hold", "oracle_v1", RULE] + [x for g in groups.values() for x in g]:
    e = [eps[a][s] for s in seeds]
    p(f"{a}: success {sum(x['success'] for x in e)}/{len(e)} touchdown {sum(x['touchdown'] for x in e)} mean return {np.mean([x['episode_return'] for x in e]):.2f}")

# ---- (3) slew
p("\n## (3) mean |change| of the damping command (EpisodeResult.damping_command_change)")
for a in ["naive", "hold", "oracle_v1", RULE] + [x for g in groups.values() for x in g]:
    v = np.array([eps[a][s]["damping_command_change"] for s in seeds])
    p(f"{a}: mean {v.mean():.4f} max over episodes {v.max():.4f} ratio to rule {v.mean() / np.mean([eps[RULE][s]['damping_command_change'] for s in seeds]):.2f}")
(A / os.environ.get("OUT", "analysis.txt")).write_text("\n".join(rep) + "\n")
