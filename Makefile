# The two commands of the README, and the trixie lane that CI runs beside them.
VENV ?= $(if $(FSI_VENV),$(FSI_VENV),.venv)
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1

.PHONY: setup demo test test-trixie lint
setup:
	scripts/setup

# The coupled moving-wall case through the 5 ms inlet pulse (20 steps, under a minute); drop
# the --set for the whole heartbeat (0.8 s).
demo: setup
	$(VENV)/bin/fsi run configs/stenosis_moving_newtonian.yaml --out results/demo --set time.end=0.005

# The tests also need Slurm (scripts/test-packages.txt) for tests/test_slurm_sweep.py.
test:
	scripts/setup --test
	scripts/test

lint: setup
	scripts/lint

test-trixie:
	scripts/trixie make test
