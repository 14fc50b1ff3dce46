"""The benchmark's chunk cache is keyed by the code that played it: a chunk cached by other code (another
plant, clock or rule) is played again, never reused (issue 20 changed the v2 plant under a cache)."""

from __future__ import annotations

import json

import gfb_experiments.benchmark_agents as bench
from gfb_agents.ladder import naive_for


def _chunk() -> bench.Chunk:
    return bench.Chunk(
        task="gfb_env/RunUp-v2",
        entry=naive_for("gfb_env/RunUp-v2"),
        run=0,
        seeds=(3_000_000,),
        split="test",
        env_kwargs={},
        record_seed=None,
    )


def test_the_key_carries_the_digest_of_the_package_sources():
    key = _chunk().key()
    assert key["code_sha256"] == bench.code_digest() and len(key["code_sha256"]) == 64


def test_a_chunk_cached_by_other_code_is_not_reused(tmp_path, monkeypatch):
    chunk = _chunk()
    bench._store(chunk, tmp_path, {"key": chunk.key(), "episodes": [], "wall_s": 0.0})
    assert bench._load_cached(chunk, tmp_path) is not None  # the same code: reused
    monkeypatch.setattr(bench, "code_digest", lambda: "0" * 64)  # the sources changed
    assert bench._load_cached(chunk, tmp_path) is None
    # a record written before the key had the digest is not reused either
    rec = json.loads(chunk.path(tmp_path).read_text())
    rec["key"].pop("code_sha256")
    chunk.path(tmp_path).write_text(json.dumps(rec))
    monkeypatch.undo()
    assert bench._load_cached(chunk, tmp_path) is None
