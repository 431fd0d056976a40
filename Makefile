# roe: convenience targets. `make demo` and `make test` each work as the only command on a fresh
# Debian bookworm machine (they install dependencies first).
BUILD ?= build
JOBS ?= $(shell nproc)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release
ROE := $(BUILD)/roe

.PHONY: all deps configure build test demo sample bench format clean install

all: build

deps:
	scripts/install-deps.sh

$(BUILD)/CMakeCache.txt:
	cmake -S . -B $(BUILD) $(CMAKE_FLAGS)

configure: $(BUILD)/CMakeCache.txt

build: configure
	cmake --build $(BUILD) -j $(JOBS)

test: deps
	$(MAKE) build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# The demo needs the roe executable only: no tests, benchmarks or image helpers (issue 24: make demo <= 8 min).
demo: deps
	$(MAKE) configure
	cmake --build $(BUILD) -j $(JOBS) --target roe
	scripts/demo.sh $(ROE)

# Regenerates the embedded default dataset datasets/sample.
sample: build
	scripts/make-sample.sh $(ROE)

# Installs roe into PREFIX (bin/roe, libexec/roe/, share/roe/); PREFIX=$$HOME/.local needs no root.
PREFIX ?= /usr/local
install: deps
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
