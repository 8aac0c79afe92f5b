# The two commands of README.md. Each sets up .venv by itself (scripts/setup.sh), quick once done.
# make run SCENE=runs/hertz.toml [OUT=DIR]; make test PYTEST_ARGS='-k hertz' (passed to pytest).
SCENE ?= runs/sphere.toml
OUT ?= results/$(basename $(notdir $(SCENE)))
PYTEST_ARGS ?=

.PHONY: setup run test
setup:
	@scripts/setup.sh

run: setup
	.venv/bin/petroll run $(SCENE) --out $(OUT)

test: setup
	scripts/test.sh $(PYTEST_ARGS)
