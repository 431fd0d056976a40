# roe: convenience targets. `make demo` and `make test` each work as the only command on a fresh
# Debian bookworm machine (they install dependencies first).
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
ROE := $(BUILD)/roe

.PHONY: all deps configure build test demo sample bench format clean install

all: build

# The Debian packages of one use (scripts/install-deps.sh: demo, test, infer, all); `make deps` = test.
DEPS ?= test
deps:
	scripts/install-deps.sh $(DEPS)

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

configure: $(BUILD)/CMakeCache.txt

build: configure
	cmake --build $(BUILD) -j $(JOBS)

test:
	scripts/install-deps.sh test
	$(MAKE) build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The demo needs the roe executable only: no tests, benchmarks or image helpers (issue 24: make demo <= 8 min).
demo:
	scripts/install-deps.sh demo
	$(MAKE) configure
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
	$(MAKE) configure
	cmake --build $(BUILD) -j $(JOBS) --target roe roe-image roe-infer
	cmake --install $(BUILD) --prefix $(PREFIX)

bench: build
	scripts/bench.sh $(BUILD)

# The libFuzzer targets (tests/fuzz/fuzz_*.cpp) in build-fuzz/ with clang, ASan and UBSan; run them with
# `scripts/fuzz.sh run SECONDS` (docs/TESTING.md, "Fuzzing").
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
	$(MAKE) configure && cmake --build $(BUILD) -j $(JOBS) --target roe roe-infer && \
	/usr/bin/python3 scripts/verify-poet-export.py --poet $(POET) --yolo $(YOLO) --ddetr $(DDETR) --roe $(ROE) --work $(VERIFY_WORK)
