# anafi_sim: the two commands of the README, and their helpers.
#   make demo   - install what is missing, build, run the main job (CONTROLLER=..., CONDITIONS=real_flights)
#   make test   - install what is missing, build, run every test (pytest, then rostest)
# Both start with `make setup`, which is idempotent (a second run only checks).
# `make bench` and `make calibrate` write into a new run folder (run/<name>-<date>-<time>-<pid>/, run/latest);
# with UPDATE=1 they rewrite the committed results instead (benchmarks/results/, anafi_sim/config/, docs/).
SHELL := /bin/bash
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))
IN_ENV := source $(ROOT)/env.bash &&
UPDATE_FLAG := $(if $(filter-out 0,$(UPDATE)),--update)

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
	@$(IN_ENV) $(ROOT)/tools/bench.sh inprocess $(UPDATE_FLAG)

bench-ros: setup
	@$(IN_ENV) $(ROOT)/tools/bench.sh ros $(UPDATE_FLAG)

lint: setup
	@$(IN_ENV) catkin_lint -W1 $(ROOT)

calibrate: setup
	@$(IN_ENV) python $(ROOT)/anafi_lab/cli/calibrate_model.py $(UPDATE_FLAG)

clean:
	rm -rf $(ROOT)/.ws $(ROOT)/env.bash $(ROOT)/test_results
