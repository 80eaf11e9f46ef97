# Two commands for a fresh machine:
#   make demo   grade the bundled example submissions (fixtures/) into demo-out/
#   make test   run the test suite (what .ci/run calls)
PYTHON ?= python3
VENV   := .venv
GRADER := $(VENV)/bin/grader

.PHONY: bootstrap demo test test-fast bench clean

bootstrap:
	@$(PYTHON) -m grader.bootstrap

demo: bootstrap
	$(GRADER) doctor
	$(GRADER) grade fixtures/submissions/enee467_lab3 --rubric rubrics/enee467_lab3.yaml -o demo-out --jobs 2
	@echo "open demo-out/index.html (one report per submission) and demo-out/grades.csv"

test: bootstrap
	$(VENV)/bin/python -m pytest $(PYTEST_ARGS)

test-fast: bootstrap
	$(VENV)/bin/python -m pytest -m "not slow" $(PYTEST_ARGS)

bench: bootstrap
	$(VENV)/bin/python -m benchmarks

clean:
	rm -rf $(VENV) demo-out .cache
