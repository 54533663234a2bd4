# example_pcl: `make demo` runs the find_can walkthrough, `make test` runs every test.
# Both first install the Debian packages (tools/setup.sh) and build the catkin workspace in build/ws.
# Everything runs on ROS's Python, /usr/bin/python3, whatever python3 comes first on PATH.

PYTHON      := /usr/bin/python3
WS          := $(CURDIR)/build/ws
DEVEL_SETUP := $(WS)/devel/setup.bash
IN_DEVEL    := bash -c 'source $(DEVEL_SETUP) && exec "$$@"' --
PYTEST_ARGS ?=

.PHONY: setup build demo test unit bench clean

setup:
	@tools/setup.sh

# The package is built as a real catkin workspace: build/ws/src/example_pcl links to this checkout.
build: setup
	@mkdir -p $(WS)/src
	@ln -sfn ../../.. $(WS)/src/example_pcl
	@cd $(WS) && catkin_make -DPYTHON_EXECUTABLE=$(PYTHON) -DCMAKE_BUILD_TYPE=Release > $(WS)/catkin_make.log 2>&1 \
	  || { tail -n 60 $(WS)/catkin_make.log; echo "build failed: full log in $(WS)/catkin_make.log"; exit 1; }
	@echo "build: ok ($(WS))"

demo: build
	@$(IN_DEVEL) tools/demo.sh

test: build
	@$(IN_DEVEL) $(PYTHON) -m pytest test $(PYTEST_ARGS)

unit: build
	@$(IN_DEVEL) $(PYTHON) -m pytest test/unit $(PYTEST_ARGS)

bench: build
	@$(IN_DEVEL) $(PYTHON) bench/run_all.py

clean:
	rm -rf build
