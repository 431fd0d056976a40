# roe: convenience targets. `make demo` and `make test` each work as the only command on a fresh
# Debian bookworm machine (they install dependencies first).
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
# ccache when the machine has it (a rebuild of an unchanged object is a cache hit; several checkouts on one
# machine share the cache where ccache's base_dir covers them). ROE_CCACHE= (empty) turns it off.
ROE_CCACHE ?= $(shell command -v ccache 2>/dev/null)
ifneq ($(ROE_CCACHE),)
CMAKE_FLAGS += -DCMAKE_CXX_COMPILER_LAUNCHER=$(ROE_CCACHE)
endif
ROE := $(BUILD)/roe
# The unity build (CMakeLists.txt, ROE_UNITY_BUILD): on for the targets that build from scratch on a user's
# machine (demo, test, install; issue 53: about half the CPU of the first build), off for `make build`, the
# developer's incremental build (one edited file recompiles alone, and ccache shares objects between
# checkouts). UNITY=ON|OFF on the command line sets it for every target.
UNITY ?=
ROE_UNITY ?= OFF
unity_for = $(if $(UNITY),$(UNITY),$(1))

.PHONY: all deps configure build test demo sample bench format clean install

all: build

# The Debian packages of one use (scripts/install-deps.sh: demo, test, infer, all); `make deps` = test.
DEPS ?= test
deps:
	scripts/install-deps.sh $(DEPS)

# Configures every time (seconds): the optional libraries (ROE_WITH_OPENCV, ROE_WITH_CERES, ROE_WITH_TORCH:
# AUTO) and the tests are looked for again, so packages installed since the last run are picked up.
# `make test` and `make install` require what they need (-D...=ON), so a missing package fails there.
WITH_ALL := -DROE_WITH_OPENCV=ON -DROE_WITH_CERES=ON
configure:
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS) -DROE_UNITY_BUILD=$(call unity_for,$(ROE_UNITY)) $(CONFIGURE_FLAGS)

build: configure
	cmake --build $(BUILD) -j $(JOBS)

test:
	scripts/install-deps.sh test
	$(MAKE) build ROE_UNITY=ON CONFIGURE_FLAGS="$(WITH_ALL) -DROE_BUILD_TESTS=ON"
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The demo needs the roe executable only: no tests, benchmarks or image helpers, and neither OpenCV nor
# Ceres (issue 38: make demo <= 4 min on a fresh 2-core bookworm; docs/install.md, scripts/time-fresh-demo.sh).
demo:
	scripts/install-deps.sh demo
	$(MAKE) configure ROE_UNITY=ON
	cmake --build $(BUILD) -j $(JOBS) --target roe
	scripts/demo.sh $(ROE)

# Regenerates the embedded default dataset datasets/sample.
sample: build
	scripts/make-sample.sh $(ROE)

# Installs roe into PREFIX (bin/roe, libexec/roe/, share/roe/); PREFIX=$$HOME/.local needs no root.
# The helpers are built here, so after `make demo` (roe alone) this installs a complete roe.
PREFIX ?= /usr/local
install:
	scripts/install-deps.sh infer
	$(MAKE) configure ROE_UNITY=ON CONFIGURE_FLAGS="$(WITH_ALL)"
	cmake --build $(BUILD) -j $(JOBS) --target roe roe-refine roe-image roe-infer
	cmake --install $(BUILD) --prefix $(PREFIX)

# The benchmarks link the image helpers' libraries: OpenCV is required (scripts/install-deps.sh infer).
bench:
	$(MAKE) build CONFIGURE_FLAGS="$(WITH_ALL)"
	scripts/bench.sh $(BUILD)

# The libFuzzer targets (tests/fuzz/fuzz_*.cpp) in build-fuzz/ with clang, ASan and UBSan; run them with
# `scripts/fuzz.sh run SECONDS` (docs/TESTING.md, "Fuzzing"). Not part of `make test`, which replays the
# targets' seed corpora through the normal build (CTest fuzz/replay/*). Needs scripts/install-deps.sh --dev.
.PHONY: fuzz
fuzz:
	JOBS=$(JOBS) scripts/fuzz.sh build

format:
	clang-format -i $$(git ls-files '*.cpp' '*.hpp')

clean:
	rm -rf $(BUILD)

# Checks scripts/export_poet.py + roe infer against the real PoET architecture (docs/infer.md, "Verified
# against the real PoET code"): make verify-poet POET=~/src/poet YOLO=~/src/yolov4 DDETR=~/src/Deformable-DETR
# [VERIFY_WORK=/tmp/roe-poet-verify]. Skips (exit 0) when Debian's python3-torch is not installed.
VERIFY_WORK ?= /tmp/roe-poet-verify
.PHONY: verify-poet
verify-poet:
	@if ! /usr/bin/python3 -c 'import torch, torchvision' 2>/dev/null; then \
	  echo "verify-poet: skipped (needs python3-torch and python3-torchvision)"; exit 0; fi; \
	test -n "$(POET)" -a -n "$(YOLO)" -a -n "$(DDETR)" || { echo "verify-poet: set POET, YOLO and DDETR (checkouts)"; exit 2; }; \
	$(MAKE) configure CONFIGURE_FLAGS="$(WITH_ALL)" && cmake --build $(BUILD) -j $(JOBS) --target roe roe-infer && \
	/usr/bin/python3 scripts/verify-poet-export.py --poet $(POET) --yolo $(YOLO) --ddetr $(DDETR) --roe $(ROE) --work $(VERIFY_WORK)
