# Entry points of the hardware-in-the-loop CAN test rig. `make` alone lists them.
# `make run` and `make test` install what is missing on first use (tools/deps) and are quick
# the second time.

SHELL := /bin/bash
.DEFAULT_GOAL := help
.SUFFIXES:

PY      := .venv/bin/python
BUILD   := build
BENCH_BUILD := build/bench
RELEASE_BUILD := build/release
OUT     ?= out
JOBS    ?= $(shell nproc)
CMAKE_FLAGS ?=

# Configure once (the cache remembers), rebuild incrementally; the protocol generator runs
# inside the build with proper dependencies.
define configure_and_build
	@test -f $(1)/build.ninja || { echo "build: configuring $(1)"; \
	  cmake -S . -B $(1) -G Ninja -DHIL_PYTHON=$(CURDIR)/$(PY) $(2) $(CMAKE_FLAGS) >/dev/null; }
	@echo "build: compiling $(1) (incremental)"
	@cmake --build $(1) -j $(JOBS) | { grep -v -E '^\[[0-9]+/[0-9]+\] ' || true; }; exit $${PIPESTATUS[0]}
endef

.PHONY: help
help: ## list the targets (default)
	@echo "Hardware-in-the-loop test rig over CAN. Targets:"
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | sed -E 's/^([a-z-]+):.*## (.*)/  make \1\t\2/' | expand -t 20
	@echo "Variables: OUT=$(OUT) (scenario output), JOBS=$(JOBS), SHARD=K/N (make test), K=EXPR (make approve), VIEWER=web, ROBOT=8 (make run), BASELINE=<commit> (make bench), DIST=DIR (make dist), CMAKE_FLAGS=..."

.PHONY: deps
deps: ## install missing Debian packages (root) and the pinned Python venv
	@tools/deps

.PHONY: build
build: deps ## build the firmware, its tests and the protocol files (build/)
	$(call configure_and_build,$(BUILD),-DCMAKE_BUILD_TYPE=RelWithDebInfo -DHIL_SANITIZE=ON -DHIL_TESTS=ON)
	$(call configure_and_build,$(RELEASE_BUILD),-DCMAKE_BUILD_TYPE=Release -DHIL_SANITIZE=OFF -DHIL_TESTS=OFF -DHIL_PORT_TESTS=ON)
	@$(MAKE) --no-print-directory fmu
	@echo "build: firmware build/bin/joint-firmware, protocol files build/protocol/board.{eds,dbc}, program download images $(RELEASE_BUILD)/images/"

.PHONY: fmu
fmu: deps ## the demo joint as an FMU (build/fmu/joint.fmu): the FMU plant's scenarios and the bench's fmu row
	@$(PY) tools/joint_fmu.py --out $(BUILD)/fmu

# The microcontroller build (issue 45): the core, the CANopen engine and the joint cross-built for a
# Cortex-M4F (cmake/arm-none-eabi.cmake): the firmware image within its flash and RAM budget, and
# the core and CANopen unit tests as images for qemu's mps2-an386. Its own tree, so build/ (the
# host's ASan build) is untouched. `make test` runs its tests, `make bench` reports its size.
CORTEX_M_BUILD := build/cortex-m

.PHONY: cortex-m
cortex-m: deps ## cross-build the firmware and its unit tests for a Cortex-M4F (build/cortex-m)
	$(call configure_and_build,$(CORTEX_M_BUILD),-DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/cmake/arm-none-eabi.cmake -DCMAKE_BUILD_TYPE=MinSizeRel -DHIL_SANITIZE=OFF -DHIL_TESTS=OFF)
	@echo "build: Cortex-M firmware image $(CORTEX_M_BUILD)/bin/joint-firmware.elf, test images $(CORTEX_M_BUILD)/bin/cm_*_tests.elf"

# The bare-metal platform (issue 62): the demo joint as an image for qemu's 32-bit Arm virt
# machine on a CTU CAN FD controller (cmake/arm-none-eabi-virt.cmake, firmware/platform/qemu-virt),
# which the marked scenarios run under qemu-system-arm (--hil-firmware-platform qemu-virt).
VIRT_BUILD := build/qemu-virt

.PHONY: baremetal
baremetal: deps ## cross-build the firmware as a bare-metal image for qemu's Arm virt machine (build/qemu-virt)
	$(call configure_and_build,$(VIRT_BUILD),-DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/cmake/arm-none-eabi-virt.cmake -DCMAKE_BUILD_TYPE=MinSizeRel -DHIL_SANITIZE=OFF -DHIL_TESTS=OFF)
	@echo "build: bare-metal image $(VIRT_BUILD)/bin/joint-firmware-virt.elf (qemu-system-arm -M virt)"

# Shards for CI (one job each): SHARD=K/N runs shard K of N of the bus-level scenarios, split by
# pytest-split from tests/.test_durations; shard 1 also runs the C++ and Python unit stages.
# Checked before anything builds: a malformed SHARD stops make with one line.
SHARD ?=
ifneq ($(SHARD),)
SHARD_ERROR := $(shell python3 tools/scenario_shards.py check '$(SHARD)' 2>&1)
ifneq ($(SHARD_ERROR),)
$(error $(SHARD_ERROR))
endif
endif

.PHONY: test
test: build cortex-m baremetal ## run everything: C++ tests, Python tests, bus-level scenarios (SHARD=K/N: one CI job of N)
	@HIL_OUT_DIR=$(CURDIR)/$(OUT) tools/run-tests $(if $(SHARD),--shard $(SHARD))

# The durations come from the JUnit XML run-tests writes rather than pytest-split's
# --store-durations: that option writes the file from every xdist worker and from each of the two
# pytest runs in turn, non-atomically; the JUnit files are the controller's record of both runs.
# Only a run that passed rewrites the file (make stops at the failing line before).
.PHONY: durations
durations: build ## run every bus-level scenario, then record their durations in tests/.test_durations
	@HIL_OUT_DIR=$(CURDIR)/$(OUT) tools/run-tests --bus-only
	@$(PY) tools/scenario_shards.py durations tests/.test_durations $(CURDIR)/$(OUT)/test-results/scenarios*.xml

# The approved traces (docs/approved-traces.md): every lockstep scenario run with
# --hil-approved=update writes its tests/approved/<test>.json anew; pytest's summary names each
# one that changed, field by field (its first cycle and both values), git's status lists them.
# K=EXPR: only the scenarios pytest's -k selects.
K ?=
.PHONY: approve
approve: build ## run the lockstep scenarios, write their approved traces anew, show what changed (K=EXPR: some)
	@mapfile -t selection < <($(PY) tools/scenario_shards.py args lockstep) || exit 2; \
	  HIL_OUT_DIR=$(CURDIR)/$(OUT) tools/with-vcan -- $(PY) -m pytest "$${selection[@]}" -q -n $(JOBS) \
	    --dist loadgroup -p no:cacheprovider --hil-approved=update $(if $(K),-k '$(K)'); \
	  status=$$?; git status --short -- tests/approved; exit $$status

# VIEWER=spawn | web[:PORT] | connect[:URL]: also stream the trace live (hilrig sim --viewer).
VIEWER ?=

# ROBOT=8: a modular robot instead of the one joint: 8 firmware modules on one bus, the chain's
# mechanics from MuJoCo, a travelling-wave gait; the trace shows the chain in 3D (out/robot).
ROBOT ?=

.PHONY: run
run: build ## the main job: firmware + rig on a vcan bus, demo scenario, summary, trace (VIEWER=web: live, ROBOT=8: a robot)
	@HIL_OUT_DIR=$(CURDIR)/$(OUT) tools/with-vcan -- $(PY) tools/run-demo.py \
	  $(if $(ROBOT),--modules $(ROBOT) --out $(CURDIR)/$(OUT)/robot,--out $(CURDIR)/$(OUT)/demo) \
	  $(if $(VIEWER),--viewer $(VIEWER))

# The README's pictures of every dashboard (docs/dashboards/), from fresh runs in one VM: the demo,
# a 4-module robot, and the demo with another seed for the diff; then headless Chromium natively.
SHOTS := $(OUT)/screenshots
.PHONY: screenshots
screenshots: build ## one picture per dashboard for the README (docs/dashboards/), from fresh make run traces
	@HIL_OUT_DIR=$(CURDIR)/$(SHOTS) tools/with-vcan -- $(CURDIR)/tools/screenshot-runs $(CURDIR)/$(SHOTS)
	@$(PY) tools/screenshots.py --demo $(SHOTS)/demo/trace.rrd --robot $(SHOTS)/robot/trace.rrd \
	  --other $(SHOTS)/demo-seed2/trace.rrd --out docs/dashboards

# BASELINE=<commit>: the commit whose engine (tools/rig_probe.py rig and engine, under callgrind)
# the report sets beside this checkout's; empty: hilrig.apps.bench.baseline's DEFAULT_BASELINE, the
# last commit before the rig's folders became its layers. Its tree is exported once into
# $(BENCH_BUILD)/baseline/ and reused (tools/bench.py baseline --remove removes it).
BASELINE ?=
BASELINE_ARG = $(if $(BASELINE),--baseline '$(BASELINE)')

.PHONY: bench
bench: deps cortex-m baremetal fmu ## benchmarks, each a ratio measured side by side in one run (BASELINE=<commit>)
	$(call configure_and_build,$(BENCH_BUILD),-DCMAKE_BUILD_TYPE=Release -DHIL_SANITIZE=OFF -DHIL_TESTS=OFF -DHIL_BENCH=ON)
	@$(PY) tools/bench.py native --out $(BENCH_BUILD) $(BASELINE_ARG)
	@HIL_BUS_PATH_FILE=$(CURDIR)/$(BENCH_BUILD)/bus-path.txt \
	  tools/with-vcan -- $(CURDIR)/$(PY) tools/bench.py bus --out $(CURDIR)/$(BENCH_BUILD)
	@$(PY) tools/bench.py report --out $(BENCH_BUILD)

.PHONY: bench-baseline
bench-baseline: deps ## only the engine vs BASELINE's, natively under callgrind (no firmware, no bus)
	@$(PY) tools/bench.py baseline --out $(BENCH_BUILD) $(BASELINE_ARG)

# The one distribution people install for bring-up, no checkout needed (tools/dist.py: the sdist
# of a staged copy of the sources, the wheel built from it; the EDS and DBC in the wheel are
# generated from protocol/board.toml then). Needs only a C compiler and the CPython headers
# (tools/deps --dist). DIST: relative to the checkout, or absolute.
DIST ?= dist

.PHONY: dist
dist: ## build what installs anywhere: dist/hilrig-*.whl and its sdist (DIST=DIR: elsewhere)
	@tools/deps --dist
	@$(PY) tools/dist.py --out $(abspath $(DIST))

# The firmware package another project's board builds against (find_package(hilfw)): the core, the
# CANopen engine, the Linux platform and the board application, as sources with their CMake config.
HILFW_PREFIX ?= dist/hilfw

.PHONY: hilfw
hilfw: deps ## install the firmware package a board's own firmware builds on (HILFW_PREFIX=dist/hilfw)
	@test -f $(BUILD)/build.ninja || $(MAKE) --no-print-directory build
	@cmake --install $(BUILD) --component hilfw --prefix $(abspath $(HILFW_PREFIX)) >/dev/null
	@echo "hilfw: installed in $(abspath $(HILFW_PREFIX)) (cmake -DCMAKE_PREFIX_PATH=$(abspath $(HILFW_PREFIX)) in a board's project)"

# Soak (issue 11): SOAK_CYCLES lockstep cycles against the real firmware on a real bus, a seeded
# fault now and then; fails if a cycle is lost or the firmware's memory grows. SOAK_ARGS are passed
# on (hilrig soak --help). Report: build/soak/report.json. Ctrl-C stops cleanly.
SOAK_CYCLES ?= 1000000
SOAK_ARGS ?=

.PHONY: soak
soak: build ## SOAK_CYCLES lockstep cycles, seeded faults; no cycle lost, memory flat (build/soak)
	@tools/soak --cycles $(SOAK_CYCLES) --out $(CURDIR)/$(BUILD)/soak $(SOAK_ARGS)

# Mutation testing: MUTANTS counted mutants of the firmware's product code (SEED), stratified over
# its files, each built in build/mutate/ (a copy of the sources: the checkout is never touched),
# then the C++ unit tests and the lockstep scenarios (one micro-VM) that execute its line (gcov,
# recorded once per source state); SHARD=K/N runs the K-th of N shards of the same sample
# (`tools/mutate.py merge` joins their reports). Report: build/mutate/report.{txt,json}.
MUTANTS ?= 40
SEED ?= 1

.PHONY: mutate
mutate: build ## mutation testing of the firmware: MUTANTS=40 (counted) SEED=1 [SHARD=K/N]; report in build/mutate
	@$(PY) tools/mutate.py run --mutants $(MUTANTS) --seed $(SEED) $(if $(SHARD),--shard $(SHARD)) \
	  --out $(CURDIR)/$(BUILD)/mutate

# Fuzzing (its own clang tree, build/fuzz): FUZZ_SECONDS per target, all targets side by side.
FUZZ_SECONDS ?= 600

.PHONY: docs
docs: deps ## build the manual from docs/ into build/site (MkDocs, strict: no broken link), command outputs checked
	@$(PY) tools/docs.py build

.PHONY: fuzz
fuzz: deps ## libFuzzer/atheris fuzzers, FUZZ_SECONDS=600 each; corpus in build/fuzz/corpus
	@FUZZ_SECONDS=$(FUZZ_SECONDS) firmware/canopen/fuzz/run-fuzzers

.PHONY: vcan
vcan: ## create vcan0 natively (needs root and a kernel with vcan)
	@if ip link show vcan0 >/dev/null 2>&1; then echo "vcan: vcan0 already exists"; \
	elif modprobe vcan 2>/dev/null; then \
	  ip link add dev vcan0 type vcan && ip link set up vcan0 && echo "vcan: vcan0 created and up"; \
	else echo "vcan: this kernel has no vcan module (or you are not root): make test and make run use the micro-VM instead (tools/with-vcan)" >&2; exit 1; fi

.PHONY: clean
clean: ## remove build/, out/ and dist/ (keeps .venv)
	@echo "clean: removing $(BUILD)/, $(OUT)/ and $(DIST)/"
	@rm -rf $(BUILD) $(OUT) $(DIST)
