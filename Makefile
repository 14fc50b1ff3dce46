# gfb-env: `make demo` runs the main job end to end, `make test` runs the tests; both bootstrap .venv.
PY ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# small matrices: threaded BLAS only thrashes on shared cores (see gfb_env/__init__.py)
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1

.PHONY: venv demo test test-slow lint format bench bench-env agents-benchmark agents-benchmark-v1 learned-v2 learning-curves-v2 clean

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

# issue 21's training campaign on the v2 ids (docs/agents.md, "The v2 training campaign"): per task PPO and
# asymmetric PPO with a 4-frame stack (5 seeds x 1M), a privileged teacher (1M) and its DAgger student (5
# seeds), SAC (5 seeds x 300k), every damping command slew-limited to 3x the best rule's mean change.
# Many hours on 2 cores: RESUMABLE, rerun `make learned-v2` and every unfinished run continues from its
# checkpoint, finished ones are skipped.  Runs go to runs/ (not committed); learning-curves-v2 draws them.
TRAIN_FLAGS := --no-tensorboard --no-progress-bar --eval-episodes 20 --eval-freq 50000 --checkpoint-freq 50000
TRAIN := $(BIN)/python -m gfb_experiments.train $(TRAIN_FLAGS) --n-jobs 2
# a distillation runs its seeds one after another (teacher_student refuses --n-jobs)
DISTILL := $(BIN)/python -m gfb_experiments.train $(TRAIN_FLAGS)
SLEW_RunUpRandomized-v2 := 0.027
SLEW_RunUp-v2 := 0.028
SLEW_WhirlRecovery-v2 := 0.0058
define campaign
	$(TRAIN) --algo ppo --frame-stack 4 --env gfb_env/$(1) --damping-slew $(SLEW_$(1)) --seeds 2-6 \
		--timesteps 1000000 --out runs/v2/$(1)_ppo_fs4
	$(TRAIN) --algo asymmetric_ppo --frame-stack 4 --env gfb_env/$(1) --damping-slew $(SLEW_$(1)) \
		--seeds 2-6 --timesteps 1000000 --out runs/v2/$(1)_asymmetric_ppo_fs4
	$(TRAIN) --algo privileged_ppo --env gfb_env/$(1) --damping-slew $(SLEW_$(1)) --seeds 0 \
		--timesteps 1000000 --out runs/v2/$(1)_teacher
	$(DISTILL) --algo teacher_student --teacher runs/v2/$(1)_teacher/seed0 --seeds 0-4 \
		--out runs/v2/$(1)_student
	$(TRAIN) --algo sac --env gfb_env/$(1) --damping-slew $(SLEW_$(1)) --seeds 0-4 --timesteps 300000 \
		--out runs/v2/$(1)_sac
endef
learned-v2: $(STAMP)
	$(call campaign,RunUpRandomized-v2)
	$(call campaign,RunUp-v2)
	$(call campaign,WhirlRecovery-v2)
	# the student of the oracle with a damping probe first (docs/agents.md, "An oracle that probes first")
	$(DISTILL) --algo teacher_student --teacher oracle --env gfb_env/RunUp-v2 --damping-slew $(SLEW_RunUp-v2) \
		--hyperparams agents/hyperparams/oracle_student.yml --timesteps 307200 --seeds 0-4 \
		--out runs/v2/RunUp-v2_oracle_probe_student_300k

# the curves of whatever the campaign has trained so far (validation seeds; results/learning_curves_v2)
learning-curves-v2: $(STAMP)
	$(BIN)/python -m gfb_experiments.learning_curves $(wildcard runs/v2/RunUpRandomized-v2_*) \
		--rules margin_aim_1x_05,margin_search_1x --out results/learning_curves_v2/RunUpRandomized-v2
	$(BIN)/python -m gfb_experiments.learning_curves $(wildcard runs/v2/RunUp-v2_*) \
		--rules margin_aim_1x_05,margin_search_1x --out results/learning_curves_v2/RunUp-v2

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
