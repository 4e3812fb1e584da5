# Two set-up commands do everything on a fresh machine:
#   make demo   - create the environment and run the main demo
#   make test   - create the environment and run the test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test env system-deps clean sample-data

# open3d links against libusb-1.0 at import time; Debian ships it as libusb-1.0-0.
system-deps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
	  echo "installing Debian package libusb-1.0-0 (needed by open3d)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -qq && $$SUDO apt-get install -y -qq libusb-1.0-0 libgl1 libgomp1 >/dev/null; \
	fi

$(STAMP): pyproject.toml
	$(MAKE) system-deps
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $(STAMP)

env: $(STAMP)

demo: $(STAMP)
	$(BIN)/tudorvision demo --out out/demo

# two worker processes (6.5-8 min on the two cores of an earlier development machine, 10.4-10.7 min on one twice as slow);
# a file's tests stay on one worker
# (module fixtures rendered once; tests/test_readme_commands.py runs its commands in order)
test: $(STAMP)
	$(BIN)/python -m pytest -n 2 --dist loadfile

clean:
	rm -rf $(VENV) out

# Regenerate the committed sample recordings (deterministic, seed 0).
SAMPLE_KINDS := stereo-step stereo-sweep stereo-checkerboard stereo-static rgbd-plane rgbd-disc rgbd-throws rgbd-wall servo-views
sample-data: $(STAMP)
	rm -rf sample_data/*/
	for k in $(SAMPLE_KINDS); do $(BIN)/tudorvision sim record $$k --small --seed 0 --out sample_data/$$k || exit 1; done
	$(BIN)/python sample_data/make_wall_calibration.py sample_data/rgbd-throws
	du -sh sample_data
