# The two commands: `make demo` and `make test`. Both install what they need first.
SHELL := /bin/bash
UMPNET := target/release/umpnet
PY := .venv/bin/python
export XDG_RUNTIME_DIR ?= /tmp

FIXTURE := $(CURDIR)/target/fixture
export UMPNET_FIXTURE := $(FIXTURE)

.PHONY: check install install-runtime install-cli wheel build py fixture demo eval-baselines eval-objects eval-fields-ablation train-baselines test test-rerun lint lint-rerun test-rust test-python mutants mutants-ci clean

install:
	@bash scripts/install.sh all

# The demo and the binary alone: no PyTorch.
install-runtime:
	@bash scripts/install.sh runtime

# `CARGO_FEATURES=--features umpnet-cli/rerun` builds Rerun recordings (`--rrd`) in.
CARGO_FEATURES ?=

build: install-runtime
	cargo build --release $(CARGO_FEATURES)

# The Python module `umpnet` (Rust, through maturin) into .venv.
py: install
	cd crates/py && ../../.venv/bin/maturin develop --release -q

# The abi3 wheel, with the shipped model inside (`umpnet.Policy.default()`),
# into target/wheels: `pip install target/wheels/umpnet-*.whl`.
wheel: install
	cd crates/py && ../../.venv/bin/maturin build --release -q -o ../../target/wheels

# `umpnet` on PATH: the binary in $(PREFIX)/bin, the shipped model in
# $(PREFIX)/share/umpnet and ONNX Runtime in $(PREFIX)/lib/umpnet, where the
# binary looks for them.
PREFIX ?= $(HOME)/.local
install-cli: build
	install -D -m 755 $(UMPNET) $(PREFIX)/bin/umpnet
	mkdir -p $(PREFIX)/share/umpnet/models $(PREFIX)/lib/umpnet
	cp -r models/umpnet-gpu-medium $(PREFIX)/share/umpnet/models/
	cp $$($(PY) -c "import onnxruntime, pathlib; print(sorted((pathlib.Path(onnxruntime.__file__).parent / 'capi').glob('libonnxruntime.so.1.*'))[-1])") $(PREFIX)/lib/umpnet/
	@echo "installed $(PREFIX)/bin/umpnet$$(case :$$PATH: in *:$(PREFIX)/bin:*) ;; *) echo "; add $(PREFIX)/bin to PATH";; esac)"

# A small untrained model package with Python onnxruntime's outputs: the runtime's contract test.
fixture: install
	cd train_py && ../.venv/bin/python -m umpnet_train.fixture $(FIXTURE)

# The main job on the shipped defaults: the learned policy (models/umpnet-gpu-medium)
# with pictures, then the benchmark against oracle and random, then speed figures.
# The pictured episodes are seed 0 of their category, by rule, not chosen for
# looking good; the benchmark's tables say how typical they are.
demo: build
	$(UMPNET) objects generate --out data/objects --per-category 20 --force
	$(UMPNET) explore --category Microwave --seed 0 --policy umpnet --out out/explore-umpnet
	$(UMPNET) goal --category Door --seed 0 --policy umpnet --out out/goal-umpnet
	$(UMPNET) explore --category StorageFurniture --seed 0 --policy oracle --out out/explore-oracle
	$(UMPNET) eval --task exploration --episodes-per-category 10 --policies umpnet,oracle,random --out out/eval-exploration --force
	$(UMPNET) eval --task goal --episodes-per-category 10 --policies umpnet,oracle,random --out out/eval-goal --force
	$(UMPNET) bench --frames 20 --actions 100
	@echo "pictures, tables and plots in out/"
	@echo "the binary is $(UMPNET); \`make install-cli\` puts \`umpnet\` on PATH (in $(PREFIX)/bin)"

# The baselines comparison: the shipped model, umpnet and the paper's baselines
# trained with one budget (models/baselines), random and oracle on the same
# scenes, both tasks. The test categories by default; SPLIT=train for the
# held-out instances of the training categories, SPLIT=all for both.
B := models/baselines
EXPLORE_POLICIES := umpnet,umpnet-300=$(B)/umpnet-300,single-step=$(B)/single-step,aot-only=$(B)/aot-only,signed-dist=$(B)/signed-dist,where2act=$(B)/where2act,where2act-normal90=$(B)/where2act-normal90,random,oracle
EPISODES ?= 50
SPLIT ?= test
eval-baselines: build
	$(UMPNET) eval --task exploration --split $(SPLIT) --episodes-per-category $(EPISODES) --policies $(EXPLORE_POLICIES) --grasp-rule affordance --out out/baselines-exploration-$(SPLIT) --force
	$(UMPNET) eval --task goal --split $(SPLIT) --episodes-per-category $(EPISODES) --policies $(EXPLORE_POLICIES),inverse=$(B)/inverse --grasp-rule affordance --out out/baselines-goal-$(SPLIT) --force

# Objects made elsewhere (docs/objects.md): every articulated object of the
# installed metaworld package, imported through MuJoCo, scored like the
# categories for the shipped model, random and the oracle, then docs/objects.md's table.
OBJECT_EPISODES ?= 50
eval-objects: build py
	$(PY) -m umpnet.objects metaworld --out data/external --force
	$(UMPNET) eval --task goal --objects data/external --episodes-per-category $(OBJECT_EPISODES) --policies umpnet,random,oracle --grasp-rule affordance --out out/external-goal --force
	$(UMPNET) eval --task exploration --objects data/external --episodes-per-category $(OBJECT_EPISODES) --policies umpnet,random,oracle --grasp-rule affordance --out out/external-exploration --force
	$(PY) scripts/objects_table.py

# The dense-articulation ablation: umpnet-300 and umpnet-300-fields (the same
# recipe and budget, plus --aux-fields 1) on the test categories and the
# Meta-World objects, then their paired differences (scripts/ablation_table.py).
ABLATION := umpnet-300=$(B)/umpnet-300,umpnet-300-fields=$(B)/umpnet-300-fields
eval-fields-ablation: build py
	$(PY) -m umpnet.objects metaworld --out data/external --force
	for t in goal exploration; do \
	  $(UMPNET) eval --task $$t --split test --episodes-per-category $(EPISODES) --policies $(ABLATION) --out out/fields-$$t-test --force && \
	  $(UMPNET) eval --task $$t --objects data/external --episodes-per-category $(EPISODES) --policies $(ABLATION) --out out/fields-$$t-objects --force || exit 1; \
	done
	$(PY) scripts/ablation_table.py --base umpnet-300 --variant umpnet-300-fields out/fields-goal-test out/fields-exploration-test out/fields-goal-objects out/fields-exploration-objects

# umpnet and every baseline with one recipe and one budget (cpu-small, 300 epochs,
# dense labels, reference physics, seed 0): an estimated 45 minutes per variant here,
# resumable across sessions (scripts/train_baselines.sh says how).
train-baselines: build py
	bash scripts/train_baselines.sh

# The `rerun` feature's code, type-checked and linted without building the SDK.
# It reads test-rerun's profile (below): the SDK's build scripts (ring's, zstd's
# and lz4's C among them) see the profile, so with one profile they run once.
RERUN := -p umpnet-cli --features umpnet-cli/rerun
RERUN_PROFILE := target/rerun-profile.toml
lint-rerun: install
	$(PY) scripts/rerun_profile.py $(RERUN_PROFILE)
	cargo clippy --release $(RERUN) --all-targets --config $(RERUN_PROFILE) -- -D warnings

# The fast inner loop: rustfmt, clippy and the Rust unit tests; no venv, no
# PyTorch, no apt (a Rust toolchain is all it needs).
check:
	cargo fmt --all --check
	cargo clippy --release --workspace --all-targets $(CARGO_FEATURES) -- -D warnings
	$(DOC)
	cargo test --release --workspace --lib --bins $(CARGO_FEATURES)

# The library crates' reference: every public item documented
# (missing_docs), every intra-doc link resolved. In the release profile, so
# rustdoc reads the dependencies' metadata that clippy --release just made
# instead of checking the whole stack again in the dev profile.
DOC = RUSTDOCFLAGS="-D warnings" cargo doc --release --no-deps -p umpnet-sim -p umpnet-policy -p umpnet-eval

lint: install
	cargo fmt --all --check
	cargo clippy --release --workspace --all-targets $(CARGO_FEATURES) -- -D warnings
	$(DOC)
	.venv/bin/ruff check tests train_py crates/py scripts benches
	.venv/bin/ruff format --check tests train_py crates/py scripts benches
	# One feature set per shared crate across test, build and maturin (crates/workspace-hack).
	$(PY) scripts/feature_sets.py

test-rust: fixture
	UMPNET_REQUIRE_WGPU=1 cargo test --release $(CARGO_FEATURES)

# pytest with the skip guard: under CI=true a skipped test fails its suite (tests/plugins/skipguard.py).
PYTEST = PYTHONPATH=tests/plugins PYTEST_ADDOPTS="-p skipguard" $(PY) -m pytest -q

test-python: build py fixture
	# One process per suite: native libraries loaded by one suite cannot affect another.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_cli_episodes.py tests/test_cli_eval.py tests/test_cli_infer.py tests/test_cli_errors.py tests/test_skipguard.py tests/test_mutant_records.py tests/test_episode_outcomes.py
	# The bad-input corpus, one file per kind, each case under a memory cap and a deadline.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_bad_inputs.py
	# Ray on a local cluster: sharded evaluation, retries.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_ray.py
	# Evaluation at any size: flat memory, resume after a kill, merging many shards.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_eval_scale.py
	# Objects made elsewhere: the MJCF importer (MuJoCo) on Meta-World, and eval --objects.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_objects.py
	# The differential suite: the `reference` physics against PyBullet.
	UMPNET_BIN=$(UMPNET) $(PYTEST) tests/reference
	# umpnet's wgpu and PyBullet's EGL renderer in one process (its own: EGL state is per process).
	$(PYTEST) tests/test_egl_coexistence.py
	$(PYTEST) crates/py/tests
	# The wheel, installed in a fresh venv outside the repository: an Env episode, Policy.default(), gym.
	bash scripts/test_wheel.sh
	UMPNET_BIN=$(UMPNET) PYTHONPATH=train_py:tests/plugins PYTEST_ADDOPTS="-p skipguard" $(PY) -m pytest -q train_py/tests

# cargo-mutants groups whose committed record (docs/mutants/) must be of the
# current sources and agree with docs/harmless-mutants.txt.
MUTANT_RECORDS ?= sim eval ideal

# The audit's deliberate bugs (and every hand-made mutant with --all below)
# must fail the tests; the cargo-mutants records must be current.
mutants-ci: build py fixture
	UMPNET_FIXTURE=$(FIXTURE) $(PY) scripts/mutants.py --ci
	$(if $(MUTANT_RECORDS),$(PY) scripts/cargo_mutants.py --check $(addprefix --group ,$(MUTANT_RECORDS)))

# Mutation testing of the core: cargo-mutants over every group (labels, the
# action, its solver, the ideal profile, the metrics, CEM, the policy and
# the observation), writing docs/mutants/; then every hand-made mutant.
# Hours on 2 cores; see docs/testing.md.
mutants: build py fixture
	command -v cargo-mutants >/dev/null || cargo install --locked cargo-mutants@27.1.0
	UMPNET_FIXTURE=$(FIXTURE) $(PY) scripts/cargo_mutants.py
	UMPNET_FIXTURE=$(FIXTURE) $(PY) scripts/mutants.py

# Last: it leaves target/release/umpnet built with Rerun, after test-python has
# checked that the default build refuses `--rrd`.
test: lint test-rust test-python mutants-ci test-rerun

# The `rerun` feature for real: lint, the readback test, and recordings made by
# the CLI. The Rerun SDK is ~300 more crates; crates/workspace-hack lets them
# share the simulator stack already built by test-rust.
# The Rerun SDK's own crates build at opt-level 0 here (scripts/rerun_profile.py
# says why); users' `--features rerun` builds keep the release profile.
test-rerun: lint-rerun fixture
	cargo test --release $(RERUN) --config $(RERUN_PROFILE)
	cargo build --release $(RERUN) --config $(RERUN_PROFILE)
	UMPNET_REQUIRE_RERUN=1 UMPNET_BIN=$(UMPNET) $(PYTEST) tests/test_cli_episodes.py -k rrd

clean:
	cargo clean
	rm -rf out runs
