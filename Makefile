# gfb-env: `make demo` runs the main job end to end, `make test` runs the tests; both bootstrap .venv.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# small matrices: threaded BLAS only thrashes on shared cores (see gfb_env/__init__.py)
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.PHONY: venv demo test test-slow lint format bench bench-env agents-benchmark agents-benchmark-v1 clean

venv: $(STAMP)

$(STAMP): pyproject.toml requirements.lock
	@test -x $(BIN)/python || $(PY) -m venv $(VENV) || python3 -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	# torch first, pinned to the CPU wheel: an unpinned torch pulls a multi-GB CUDA build
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -r requirements.lock
	$(BIN)/python -m pip install -q --no-deps -e .
	@touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python -m gfb_experiments.demo --out results/demo

test: $(STAMP)
	$(BIN)/python -m pytest -q

test-slow: $(STAMP)
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check gfb_env agents experiments tests
	$(BIN)/ruff format --check gfb_env agents experiments tests

format: $(STAMP)
	$(BIN)/ruff format gfb_env agents experiments tests
	$(BIN)/ruff check --fix gfb_env agents experiments tests

bench: $(STAMP)
	$(BIN)/python -m gfb_experiments.bench_integrator
	$(BIN)/python -m gfb_experiments.bench_friction

bench-env: $(STAMP)
	$(BIN)/python -m gfb_experiments.bench_env

# the v2 table (issue 19): 200 test seeds per task (RunUpRandomized-v2's rules cost 12-17 s an episode);
# resumable: a rerun skips the finished chunks
agents-benchmark: $(STAMP)
	$(BIN)/python -m gfb_experiments.benchmark_agents --split test --episodes 200 --n-jobs 2 --no-learned \
		--tasks gfb_env/WhirlRecovery-v2
	$(BIN)/python -m gfb_experiments.benchmark_agents --split test --episodes 200 --n-jobs 2 --no-learned \
		--tasks gfb_env/RunUp-v2 --merge
	$(BIN)/python -m gfb_experiments.benchmark_agents --split test --episodes 200 --n-jobs 2 --no-learned \
		--tasks gfb_env/RunUpRandomized-v2 --merge

# the record of the retired v1 ids (results/benchmark_v1, not a benchmark: their info and reward leak the
# hidden plant; the runner builds them with gfb_env.envs.make_retired): the recorded command (its
# episodes; today's statistics), about an hour on 2 cores; resumable
agents-benchmark-v1: $(STAMP)
	$(BIN)/python -m gfb_experiments.benchmark_agents --split test --episodes 100 --n-jobs 2 \
		--tasks gfb_env/RunUp-v1,gfb_env/RunUpRandomized-v1,gfb_env/WhirlRecovery-v1 --out results/benchmark_v1

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
