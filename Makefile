# anafi_sim: the two commands of the README, and their helpers.
#   make demo   - install what is missing, build, run the main job (CONTROLLER=..., CONDITIONS=real_flights)
#   make test   - install what is missing, build, run every test (pytest, then rostest)
# Both start with `make setup`, which is idempotent (a second run only checks).
SHELL := /bin/bash
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))
IN_ENV := source $(ROOT)/env.bash &&

.PHONY: setup demo test unit rostest bench bench-ros lint calibrate clean

setup:
	@$(ROOT)/tools/setup.sh

demo: setup
	@$(IN_ENV) $(ROOT)/tools/demo.sh

test: setup
	@$(IN_ENV) python $(ROOT)/tools/run_tests.py

unit: setup
	@$(IN_ENV) python $(ROOT)/tools/run_tests.py --unit-only

rostest: setup
	@$(IN_ENV) python $(ROOT)/tools/run_tests.py --rostest-only

bench: setup
	@$(IN_ENV) $(ROOT)/tools/bench.sh inprocess

bench-ros: setup
	@$(IN_ENV) $(ROOT)/tools/bench.sh ros

lint: setup
	@$(IN_ENV) catkin_lint -W1 $(ROOT)

calibrate: setup
	@$(IN_ENV) python $(ROOT)/anafi_lab/cli/calibrate_model.py

clean:
	rm -rf $(ROOT)/.ws $(ROOT)/env.bash $(ROOT)/test_results
