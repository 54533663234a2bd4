# example_pcl: `make demo` runs the find_can walkthrough, `make test` runs every test.
# Both first install the Debian packages (tools/setup.sh) and build the catkin workspace in build/ws.
# Everything runs on ROS's Python, /usr/bin/python3, whatever python3 comes first on PATH.

PYTHON      := /usr/bin/python3
WS          := $(CURDIR)/build/ws
DEVEL_SETUP := $(WS)/devel/setup.bash
IN_DEVEL    := bash -c 'source $(DEVEL_SETUP) && exec "$$@"' --
PYTEST_ARGS ?=
BUILD_BENCH ?= OFF

.PHONY: setup build demo demo-tracker test unit bench screenshots clean

setup:
	@tools/setup.sh

# The package is built in a real catkin workspace, build/ws. Its src/example_pcl holds links to this
# checkout's top-level entries except build/ itself: a link to the whole checkout would put the
# workspace inside its own package (a loop that rosrun's `find -L` walks into).
build: setup
	@if [ -L $(WS)/src/example_pcl ]; then rm $(WS)/src/example_pcl; fi
	@mkdir -p $(WS)/src/example_pcl
	@find $(WS)/src/example_pcl -maxdepth 1 -type l -delete
	@for entry in $(filter-out $(CURDIR)/build,$(wildcard $(CURDIR)/*)); do ln -s $$entry $(WS)/src/example_pcl/; done
	@if [ ! -f $(WS)/build/CMakeCache.txt ]; then rm -rf $(WS)/build; fi
	@cd $(WS) && catkin_make -DPYTHON_EXECUTABLE=$(PYTHON) -DCMAKE_BUILD_TYPE=Release \
	  -DEXAMPLE_PCL_BUILD_BENCH=$(BUILD_BENCH) > $(WS)/catkin_make.log 2>&1 \
	  || { tail -n 60 $(WS)/catkin_make.log; echo "build failed: full log in $(WS)/catkin_make.log"; exit 1; }
	@echo "build: ok ($(WS))"

demo: build
	@$(IN_DEVEL) tools/demo.sh

# can_tracker on a generated moving stream at 30 Hz; prints the tracks. RVIZ=true also opens rviz.
RVIZ ?= false
demo-tracker: build
	@$(IN_DEVEL) tools/demo_tracker.sh $(if $(filter true,$(RVIZ)),rviz)

test: build
	@$(IN_DEVEL) $(PYTHON) -m pytest test $(PYTEST_ARGS)

unit: build
	@$(IN_DEVEL) $(PYTHON) -m pytest test/unit $(PYTEST_ARGS)

# Open3D (not in Debian) goes into a benchmark-only venv; the figures are written into docs/benchmarks.md.
# The C++ benchmark programs (bench/*.cpp) are built only here (BUILD_BENCH=ON reaches `build`).
bench: BUILD_BENCH = ON
bench: build
	@bench_python=$$(tools/bench_env.sh build/bench-venv) && \
	  PCD_IO_PCL=$(WS)/devel/lib/example_pcl/bench/pcd_io_pcl $(IN_DEVEL) $$bench_python bench/run_all.py

# The rviz pictures (docs/rviz/*.jpg): the operator test in a real rviz under Xvfb saves each step.
screenshots: build
	@EXAMPLE_PCL_SCREENSHOTS=$(CURDIR)/docs/rviz $(IN_DEVEL) $(PYTHON) -m pytest test/integration/test_rviz_operator.py $(PYTEST_ARGS)

clean:
	rm -rf build
