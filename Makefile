# rosgate: `make run` starts the gateway with the embedded sim and the IDE; `make test` runs every test.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
ARGS   ?=
# In a shell where ROS 2 is sourced, the venv sees the system's rclpy (the gateway then picks it).
VENV_FLAGS := $(if $(ROS_DISTRO),--system-site-packages,)

.PHONY: run test test-rclpy bench install install-test ide clean system system-test

# The rclpy backend's contract suite runs against real rclpy (Jazzy builds from PyPI) in a separate
# environment, inside a network namespace with only loopback: DDS discovery stays on this machine.
ROSVENV  := .venv-ros
# What the suite needs besides the project's [ros] and [ros-build] extras (rclpy with Fast DDS,
# common_interfaces; the generators that build the test robot's interfaces and types on first use),
# and a robot on Cyclone DDS for the cross-vendor test; colcon builds the IDE's ROS 2 package download,
# which Chromium (Playwright; websockets for tests/support) fetches from the IDE (test_ros_package.py).
ROS_TEST_PKGS := ros-jazzy-test-msgs==2.0.3 cyclonedds==11.0.1 pytest pytest-asyncio pytest-timeout hypothesis \
                 colcon-core==0.21.3 colcon-ros==0.5.0 playwright==1.65.2 websockets==17.4

system:
	@tools/system-packages run

system-test:
	@tools/system-packages test

$(PY): | system
	$(PYTHON) -m venv $(VENV_FLAGS) $(VENV) || { echo "python3 -m venv failed: install python3-venv (apt-get install python3-venv)"; exit 1; }
	$(PY) -m pip install -q --upgrade pip

$(VENV)/.installed: pyproject.toml | $(PY)
	$(PY) -m pip install -q -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml $(VENV)/.installed
	$(PY) -m pip install -q -e '.[test,bench]'
	touch $@

ide/vendor/.built: ide/package.json ide/package-lock.json ide/build.mjs | system
	cd ide && npm ci --no-audit --no-fund && npm run build
	touch $@

tests/node/node_modules/.installed: tests/node/package.json tests/node/package-lock.json
	cd tests/node && npm ci --no-audit --no-fund
	touch $@

install: $(VENV)/.installed
install-test: $(VENV)/.installed-test
ide: ide/vendor/.built

run: install ide
	$(PY) -m gateway --robot turtlesim $(ARGS)

# pytest runs the suite in three parallel test processes (pytest-xdist), at most 4: it waits on
# robots, browsers and links more than it computes (on 2 cores, two processes kept the CPU 41 %
# busy for 19 min; three took 14 min); a file is the unit a process takes (tests/support/schedule.py).
# `make test TEST_PROCS=0` runs it in one.
TEST_PROCS ?= 3
test: system-test install-test ide tests/node/node_modules/.installed $(ROSVENV)/.installed
	$(PY) -m pytest -q -n $(TEST_PROCS) --maxprocesses 4 --no-loadscope-reorder tests
	cd tests/node && node --test
	$(MAKE) --no-print-directory test-rclpy

$(ROSVENV)/.installed: pyproject.toml Makefile
	$(PYTHON) -m venv $(ROSVENV)
	$(ROSVENV)/bin/pip install -q -e '.[ros,ros-build,postgres]' $(ROS_TEST_PKGS)
	touch $@

# As root a network namespace alone (unshare -n): a user namespace that maps uid 0 alone (unshare -rn
# run by root) has no unprivileged uid to give the robot-side runs, which would be root outside.
NETNS := $(if $(filter 0,$(shell id -u)),unshare -n,unshare -rn)

test-rclpy: $(ROSVENV)/.installed ide
	$(NETNS) sh -c 'ip link set lo up && $(ROSVENV)/bin/python -m pytest -q tests/backends tests/install/test_ros_extra.py'

bench: install-test $(if $(findstring rclpy,$(ARGS)),$(ROSVENV)/.installed-bench)
	$(PY) -m tests.bench $(ARGS)
	$(if $(ARGS),,$(PY) -m tests.bench pyodide --repeat 3)

# `make bench ARGS="--backend rclpy"` also measures the Rust rosbridge server on the same wheels
$(ROSVENV)/.installed-bench: $(ROSVENV)/.installed
	$(ROSVENV)/bin/pip install -q rosbridge-server-rs==0.1.6
	touch $@

clean:
	rm -rf $(VENV) $(ROSVENV) ide/node_modules ide/vendor tests/node/node_modules
