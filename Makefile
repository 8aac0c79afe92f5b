# The two commands of README.md. Each sets up .venv by itself (scripts/setup.sh), quick once done.
# make run SCENE=runs/hertz.toml [OUT=DIR]; make test PYTEST_ARGS='-k hertz' (passed to pytest).
# make check: the fast tier (under 2 minutes; docs/contributing.md), make test the whole suite.
SCENE ?= runs/sphere.toml
OUT ?= results/$(basename $(notdir $(SCENE)))
PYTEST_ARGS ?=

.PHONY: setup run test check
setup:
	@scripts/setup.sh

run: setup
	.venv/bin/petroll run $(SCENE) --out $(OUT)

test: setup
	scripts/test.sh $(PYTEST_ARGS)

check: setup
	scripts/test.sh --fast $(PYTEST_ARGS)
