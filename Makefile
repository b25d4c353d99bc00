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
# chromium-driver: the headless browser that checks replay.html (tests/test_replay.py) and the later web UIs;
# mona: needed by later issues.
APT_PACKAGES := $(BUILD_PACKAGES) libeigen3-dev libembree-dev libbullet-dev libgtest-dev libbenchmark-dev \
                libusb-1.0-0 libgl1 libegl1 libx11-6 libtbb12 chromium chromium-driver mona
# Build tools installed into the venv (no build isolation, so rebuilds are incremental).
BUILD_TOOLS := "scikit-build-core>=0.10" "pybind11>=3.1,<3.2" "cmake>=3.18" ninja

SOURCES := $(shell find cpp bindings -type f \( -name '*.cpp' -o -name '*.h' -o -name CMakeLists.txt \)) \
           CMakeLists.txt pyproject.toml
CPP_BUILD := build/cpp
SAN_BUILD := build/sanitize

.PHONY: demo test test-cpp test-python bench sanitize deps stubs clean

# The paper's §3.1 case study; prints the metrics and where the run folder is.
demo: $(VENV)/.installed
	$(VENV)/bin/cufund run square

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
	CMAKE_BUILD_PARALLEL_LEVEL=$(JOBS) $(VPIP) install -q --no-build-isolation -e '.[test]'
	touch $@

$(CPP_BUILD)/build.ninja: $(VENV)/.tools CMakeLists.txt $(wildcard cpp/*/CMakeLists.txt)
	$(MAKE) deps
	$(VENV)/bin/cmake -S . -B $(CPP_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_BUILD_TYPE=Release -DCUFUND_BUILD_TESTS=ON -DCUFUND_BUILD_BENCHMARKS=ON -DCUFUND_BUILD_PYTHON=OFF

test-cpp: $(CPP_BUILD)/build.ninja
	$(VENV)/bin/cmake --build $(CPP_BUILD) -j $(JOBS)
	$(VENV)/bin/ctest --test-dir $(CPP_BUILD) --output-on-failure -j $(JOBS)

test-python: $(VENV)/.installed
	$(VPY) -m pytest -q

sanitize: $(VENV)/.tools
	$(MAKE) deps
	$(VENV)/bin/cmake -S . -B $(SAN_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCUFUND_BUILD_TESTS=ON -DCUFUND_SANITIZE=ON -DCUFUND_BUILD_PYTHON=OFF
	$(VENV)/bin/cmake --build $(SAN_BUILD) -j $(JOBS)
	ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
	  $(VENV)/bin/ctest --test-dir $(SAN_BUILD) --output-on-failure -j $(JOBS)

CPP_BENCHES := dynamics lidar esdf
PY_BENCHES := $(wildcard benchmarks/bench_*.py)

bench: $(VENV)/.installed $(CPP_BUILD)/build.ninja
	$(VENV)/bin/cmake --build $(CPP_BUILD) -j $(JOBS) --target $(addprefix bench_,$(CPP_BENCHES))
	set -e; for b in $(CPP_BENCHES); do $(CPP_BUILD)/cpp/$$b/bench_$$b --benchmark_min_time=0.2; done
	set -e; for b in $(PY_BENCHES); do $(VPY) $$b; done

# Regenerates the checked-in type stubs from the compiled module (tests/test_stubs.py checks them).
stubs: $(VENV)/.installed
	$(VPY) -m pybind11_stubgen cufund._core -o python --numpy-array-use-type-var

clean:
	rm -rf build $(VENV) *.egg-info
