# Two commands for a fresh machine:
#   make demo   grade the bundled example submissions of every lab (fixtures/) into demo-out/<lab>/
#   make test   run the test suite (what .ci/run calls)
PYTHON ?= python3
VENV   := .venv
GRADER := $(VENV)/bin/grader

.PHONY: bootstrap demo test test-fast test-heavy test-slurm bench clean

bootstrap:
	@$(PYTHON) -m grader.bootstrap

LABS := enee467_lab3 goal_setter wall_pen first_nodes

demo: bootstrap
	$(GRADER) doctor
	@for lab in $(LABS); do \
	  echo "== $$lab"; \
	  $(GRADER) grade fixtures/submissions/$$lab --rubric rubrics/$$lab.yaml -o demo-out/$$lab || exit $$?; \
	done
	@echo "open demo-out/<lab>/index.html (the class view, one report per submission) and demo-out/<lab>/grades.csv"

# everything but the heavy tests (~25 min on 2 cores); CI (.ci/run) runs test-heavy after it
test: bootstrap
	$(VENV)/bin/python -m pytest -m "not heavy" $(PYTEST_ARGS)

test-fast: bootstrap
	$(VENV)/bin/python -m pytest -m "not slow and not heavy" $(PYTEST_ARGS)

# the longest end-to-end tests: every fixture of every lab, the fault corpus, a real Slurm
# cluster, installs from git/pipx, the Gradescope image (see the `heavy` marker)
test-heavy: bootstrap
	$(VENV)/bin/python -m pytest -m heavy $(PYTEST_ARGS)

# the Slurm example on a real single-node Slurm (slurmctld + slurmd started and stopped by the
# test; part of `make test-heavy` too)
test-slurm: bootstrap
	$(VENV)/bin/python -m pytest tests/scale/test_slurm.py $(PYTEST_ARGS)

bench: bootstrap
	$(VENV)/bin/python -m benchmarks

clean:
	rm -rf $(VENV) demo-out .cache
