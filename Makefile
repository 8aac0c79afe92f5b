# The two commands of README.md. Each sets up .venv by itself (scripts/setup.sh), quick once done.
SCENE ?= runs/sphere.toml
OUT ?= results/$(basename $(notdir $(SCENE)))

.PHONY: setup run test
setup:
	@scripts/setup.sh

run: setup
	.venv/bin/petroll run $(SCENE) --out $(OUT)

test: setup
	scripts/test.sh
