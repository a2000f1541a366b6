# The two commands of the README, and the trixie lane that CI runs beside them.
VENV ?= $(if $(FSI_VENV),$(FSI_VENV),.venv)
export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1

.PHONY: setup demo test test-trixie
setup:
	scripts/setup

demo: setup
	$(VENV)/bin/fsi mesh configs/stenosis_fixed_newtonian.yaml --out results/demo

test: setup
	scripts/test

test-trixie:
	scripts/trixie make test
