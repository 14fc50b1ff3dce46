"""Audit: every seed list in results/learned_v2 and agents/policies/*v2* records vs the splits."""
import json
from pathlib import Path
from gfb_agents.seeds import TRAIN, VALIDATION, TEST, DEV, LEGACY_V0

def walk(obj, path=""):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from walk(v, f"{path}.{k}")
    elif isinstance(obj, list):
        if obj and all(isinstance(x, int) and not isinstance(x, bool) for x in obj):
            yield path, obj
        else:
            for i, v in enumerate(obj):
                yield from walk(v, f"{path}[{i}]")
    elif isinstance(obj, int) and not isinstance(obj, bool) and "seed" in path.lower():
        yield path, [obj]

def split_of(s):
    for r in (TRAIN, VALIDATION, TEST, DEV, LEGACY_V0):
        if s in r:
            return r.name
    return "none"

files = sorted(Path("/work/main/results/learned_v2").rglob("*.json")) + sorted(
    Path("/work/main/agents/policies").glob("RunUpRandomized-v2_*/seed*/policy.json"))
bad = 0
for f in files:
    d = json.loads(f.read_text())
    for path, seeds in walk(d):
        if "seed" not in path.lower():
            continue
        splits = sorted({split_of(s) for s in seeds})
        tag = "" if "test" not in splits else "  <-- TEST SEED"
        bad += bool(tag)
        if len(seeds) > 3:
            print(f"{f.relative_to('/work/main')}:{path}: n={len(seeds)} [{min(seeds)}..{max(seeds)}] splits={splits}{tag}")
        else:
            print(f"{f.relative_to('/work/main')}:{path}: {seeds} splits={splits}{tag}")
print("records with a TEST seed:", bad)
