# kinesplat — top-level entry points. `make demo` and `make test` work on a fresh Debian 12 machine.
BUILD_DIR ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?=
DEMO_DIR ?= demo-out

DEB_PACKAGES := build-essential cmake ninja-build pkg-config libeigen3-dev libopencv-dev \
  nlohmann-json3-dev libcli11-dev libgtest-dev libbenchmark-dev zlib1g-dev ffmpeg libceres-dev \
  chromium blender python3-numpy libcpp-httplib-dev
# The perceive helper (Node): its packages pinned by its package-lock.json, its models by models.json.
PERCEIVE_HELPER := helpers/perceive

.PHONY: deps node perceive-helper viewer gltf-validator gltf-browser build test test-slurm test-sanitize fuzz fuzz-build fuzz-corpus demo demo-true-frames bench format clean

deps:
	@missing=""; for p in $(DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "kinesplat: installing missing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -ne 0 ] && SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	else echo "kinesplat: all Debian packages present"; fi
	@$(MAKE) --no-print-directory node perceive-helper viewer gltf-validator gltf-browser

# Node.js and npm (Debian's where there are none): the perceive helper and the viewer run on them.
node:
	@if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then \
	  echo "kinesplat: installing Node.js and npm (Debian packages)"; \
	  SUDO=""; [ "$$(id -u)" -ne 0 ] && SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends nodejs npm; \
	fi

# The perceive helper (helpers/perceive, docs/perceive.md): its pinned npm packages, then its models
# (one pinned tarball, checked by its sha512).
perceive-helper: node
	@cd $(PERCEIVE_HELPER) && if ! cmp -s package-lock.json node_modules/.kinesplat-lock 2>/dev/null; then \
	  echo "kinesplat: installing the perceive helper's Node packages (npm ci in $(PERCEIVE_HELPER))"; \
	  npm ci --ignore-scripts --no-audit --no-fund --loglevel=error && cp package-lock.json node_modules/.kinesplat-lock; \
	fi
	@node $(PERCEIVE_HELPER)/install-models.js

# The browser viewer (viewer/, docs/viewer.md): the pinned npm packages (viewer/package-lock.json),
# then the bundle in viewer/dist. A failure here leaves `view` / `export --web` unavailable and
# their browser test skipped, not the build broken.
viewer: node
	@cd viewer && { [ -f node_modules/.package-lock.json ] && [ ! package-lock.json -nt node_modules/.package-lock.json ] \
	  || npm ci --no-audit --no-fund --loglevel=error; } && npm run --silent build \
	  && echo "kinesplat: viewer built in viewer/dist" \
	  || echo "kinesplat: WARNING: the browser viewer could not be installed or built (see above)"

# Khronos glTF-Validator (npm gltf-validator, pinned by tests/gltf/validator/package-lock.json) for
# the glTF export's test (docs/export.md); without it that test skips, saying so.
gltf-validator: node
	@cd tests/gltf/validator && if ! cmp -s package-lock.json node_modules/.kinesplat-lock 2>/dev/null; then \
	  echo "kinesplat: installing glTF-Validator (npm ci in tests/gltf/validator)"; \
	  npm ci --ignore-scripts --no-audit --no-fund --loglevel=error && cp package-lock.json node_modules/.kinesplat-lock \
	  || echo "kinesplat: WARNING: glTF-Validator could not be installed (its test will skip)"; \
	fi

# The glTF export's browser check (tests/gltf/browser, docs/export.md): three.js and Babylon.js,
# pinned by tests/gltf/browser/package-lock.json; without them that test skips, saying so.
gltf-browser: node
	@cd tests/gltf/browser && if ! cmp -s package-lock.json node_modules/.kinesplat-lock 2>/dev/null; then \
	  echo "kinesplat: installing the glTF browser check's packages (npm ci in tests/gltf/browser)"; \
	  npm ci --ignore-scripts --no-audit --no-fund --loglevel=error && cp package-lock.json node_modules/.kinesplat-lock \
	  || echo "kinesplat: WARNING: the glTF browser check's packages could not be installed (its test will skip)"; \
	fi

build:
	cmake -S . -B $(BUILD_DIR) -G Ninja -DCMAKE_BUILD_TYPE=Release $(CMAKE_FLAGS)
	cmake --build $(BUILD_DIR) -j $(JOBS)

test: deps build
	cd $(BUILD_DIR) && ctest -j $(JOBS) --output-on-failure

# `kinesplat batch --scheduler slurm` on a real one-node Slurm cluster on loopback (docs/batch.md):
# installs slurm-wlm and munge where missing, starts and stops the daemons itself. Needs root.
test-slurm: build
	./scripts/test_slurm.sh $(BUILD_DIR)/kinesplat

# The whole test suite built with AddressSanitizer + UndefinedBehaviorSanitizer in its own build dir
# (docs/robustness.md). Any report fails the test that triggered it (abort, not exit 1).
SANITIZE_DIR ?= build-sanitize
SANITIZE_FLAGS := -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
# The loopback Slurm test's three items run several times slower under the sanitizers: its batch
# gets 30 minutes and ctest 40 per test.
SANITIZE_ENV := KS_SLURM_TIMEOUT=1800 ASAN_OPTIONS=abort_on_error=1:detect_leaks=1:strict_string_checks=1 \
  UBSAN_OPTIONS=print_stacktrace=1:abort_on_error=1:halt_on_error=1
test-sanitize: deps
	cmake -S . -B $(SANITIZE_DIR) -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DKS_BUILD_BENCH=OFF \
	  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_CXX_FLAGS="$(SANITIZE_FLAGS)" \
	  -DCMAKE_EXE_LINKER_FLAGS="$(SANITIZE_FLAGS)" -DKS_TEST_TIMEOUT=2400 $(CMAKE_FLAGS)
	$(SANITIZE_ENV) cmake --build $(SANITIZE_DIR) -j $(JOBS)
	cd $(SANITIZE_DIR) && $(SANITIZE_ENV) ctest -j $(JOBS) --output-on-failure

# libFuzzer harnesses (fuzz/, docs/robustness.md): clang with ASan + UBSan, built in build-fuzz.
# Optional: needs clang and libFuzzer (Debian's `clang` and `libclang-rt-dev`, installed here when
# missing); `make test` does not.
# `make fuzz` runs each harness FUZZ_SECONDS on its seed corpus (made by the project's own writers)
# plus what earlier runs found (fuzz/corpus/<name>, git-ignored); crashes land in fuzz/crashes/.
FUZZ_DIR ?= build-fuzz
FUZZ_SECONDS ?= 180
FUZZ_TARGETS ?= $(notdir $(basename $(wildcard fuzz/fuzz_*.cpp)))
FUZZ_DEB_PACKAGES := clang libclang-rt-dev
fuzz-build:
	@missing=""; for p in $(FUZZ_DEB_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "kinesplat: installing missing Debian packages for fuzzing:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -ne 0 ] && SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi
	CC=clang CXX=clang++ cmake -S fuzz -B $(FUZZ_DIR) -G Ninja
	cmake --build $(FUZZ_DIR) -j $(JOBS)
fuzz-corpus: fuzz-build
	$(FUZZ_DIR)/fuzz_seeds $(FUZZ_DIR)/seeds
fuzz: fuzz-corpus
	./fuzz/run.sh $(FUZZ_DIR) $(FUZZ_SECONDS) $(FUZZ_TARGETS)

demo: deps build
	./scripts/demo.sh $(BUILD_DIR)/kinesplat $(DEMO_DIR)

# The avatar from the synth's true multi-view frames (no photo front end).
demo-true-frames: deps build
	./scripts/demo_true_frames.sh $(BUILD_DIR)/kinesplat $(DEMO_DIR)-true-frames

# The rasterizer benchmark at the project's reference size (the README's figures), then the
# Google Benchmark programs (rasterizer, decoder MLPs, the fit's Adam step and triplane).
bench: deps build
	$(BUILD_DIR)/kinesplat bench raster --gaussians 110000 --width 512 --height 768 --backward --frames 10
	$(BUILD_DIR)/raster_bench
	$(BUILD_DIR)/mlp_bench
	$(BUILD_DIR)/train_step_bench

format:
	find src tests bench -name '*.cpp' -o -name '*.hpp' | xargs clang-format -i

clean:
	rm -rf $(BUILD_DIR) $(SANITIZE_DIR) $(FUZZ_DIR)
