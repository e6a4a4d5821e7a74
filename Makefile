# Two commands do all set-up on a fresh machine (see README.md):
#   make demo   build the environment and run the main job on the sample scenes
#   make test   build the environments and run the whole test suite (what CI runs)
# Inner loop: make test-quick (tests not marked slow); documents: make docs.
SHELL := /bin/bash
VENV   := .venv
VENV45 := .venv45
PY     := $(VENV)/bin/python
PY45   := $(VENV45)/bin/python
OUT    ?= out
# Keep the test suite inside the 2-core machine: one process, hypothesis profile "ci".
PYTEST_FLAGS ?= -q -p no:cacheprovider

.PHONY: all demo test test-quick test-kernels test-farm test-blender test-blender45 lint samples extension bench \
	docs clean chromium

all: test

$(VENV)/.stamp: requirements/blender52.txt requirements/dev.txt tools/make_venv.sh
	tools/make_venv.sh 3.13 $(VENV) requirements/blender52.txt requirements/dev.txt

$(VENV45)/.stamp: requirements/blender45.txt tools/make_venv.sh
	tools/make_venv.sh 3.11 $(VENV45) requirements/blender45.txt

demo: $(VENV)/.stamp
	$(PY) -m classic_bake demo sample_blends --out $(OUT)/demo

test: lint test-kernels test-farm test-blender test-blender45

# The Flamenco job type's compiler (farm/), with Node's own test runner; one line and a skip
# where Node is missing.
test-farm:
	@if command -v node >/dev/null; then node --test farm/; else echo "test-farm: node not found, skipped"; fi

lint: $(VENV)/.stamp
	$(VENV)/bin/ruff check .

# The report's browser test needs Chromium: installed when possible (root or passwordless sudo, apt-get),
# otherwise one line says why and the test skips. Never fails the build; a no-op when present.
chromium:
	tools/install_chromium.sh

test-kernels: $(VENV)/.stamp chromium
	$(PY) -m pytest $(PYTEST_FLAGS) tests/kernels tests/pipeline

test-blender: $(VENV)/.stamp
	$(PY) -m pytest $(PYTEST_FLAGS) tests/blender

# The inner loop: lint and every test not marked slow (pytest -m "not slow"), on Blender 5.2 only.
test-quick: lint $(VENV)/.stamp
	$(PY) -m pytest $(PYTEST_FLAGS) -m "not slow" tests/kernels tests/pipeline tests/blender

# Compatibility run on the previous LTS (bpy 4.5, CPython 3.11): the tests of what differs between
# Blender versions (the bridge, materials and worlds, the interface, properties, installing, the
# outputs written into Blender), not marked slow. The 5.2 run has every test, with the pipeline's
# command-line catalogues and the slow comparisons with converged Cycles renders. So CI stays
# under 20 minutes.
BLENDER45_TESTS := $(addprefix tests/blender/,test_interface.py test_world.py test_records.py \
	test_material_graphs.py test_shader_graphs.py test_color_attributes.py test_udim_images.py \
	test_envmap_outputs.py \
	test_normalmap.py test_normalmap_tangents.py test_normalmap_high_to_low.py \
	test_normalmap_frames.py \
	test_snapshot.py test_write_back.py test_light_units.py test_install.py \
	test_lightmap_operator.py test_camera_views.py test_sample_scenes.py test_texture_bake.py \
	test_bump.py test_trace.py test_shadowmap_bake.py \
	test_radiosity_bake.py test_cycles_reference.py test_cycles_albedo.py \
	test_light_linking.py)
test-blender45: $(VENV45)/.stamp
	$(PY45) -m pytest $(PYTEST_FLAGS) -m "not slow" $(BLENDER45_TESTS)

samples: $(VENV)/.stamp
	$(PY) sample_blends/make_samples.py

extension: $(VENV)/.stamp
	$(PY) tools/build_extension.py --out dist

# Every benchmark (bench/_report.py and bench/meshes.py are their shared helpers).
BENCHES := rays rays_loaded trace texture envmap envmap_eevee bump shadowmap radiosity hybrid normalmap generated batch demo

# Every bench, then their reports published into bench/results/ and the documents regenerated.
# Run it on an idle machine: a second busy process halves NumPy's speed on two cores.
bench: $(VENV)/.stamp
	for b in $(BENCHES); do $(PY) bench/$$b.py || exit 1; done
	$(PY) tools/gen_docs.py --publish

# The documents' generated blocks: parameters from the settings dataclasses, figures from
# bench/results/ (PUBLISH=1: first copy the reports the benches wrote into out/bench/).
docs: $(VENV)/.stamp
	$(PY) tools/gen_docs.py $(if $(PUBLISH),--publish)

clean:
	rm -rf $(OUT) dist wheels
