"""The GIL is released while a frame runs; the documentation teaches; the config round-trips."""

import doctest
import threading

import numpy as np

import viscd
from conftest import brute_sphere_pairs, random_spheres


def test_gil_is_released_during_a_frame(rng):
    # While one thread runs a long frame, this thread runs Python and reaches the same Detector,
    # which refuses the concurrent call: both can only happen when detect() released the GIL.
    spheres = random_spheres(rng, 400_000, extent=600.0, r_min=0.05, r_max=0.5)
    det = viscd.Detector(threads=1)
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault("frame", det.detect(spheres)))
    busy_seen = 0
    python_steps = 0
    worker.start()
    while worker.is_alive():
        python_steps += 1
        try:
            det.ray_cast((0, 0, 0), (1, 0, 0))
        except RuntimeError as e:
            assert "another thread" in str(e)
            busy_seen += 1
    worker.join()
    assert busy_seen > 0, f"this thread never ran during the frame ({python_steps} steps)"
    assert result["frame"].stats["objects"] == 400_000


def test_detectors_in_threads(rng):
    scenes = [random_spheres(rng, 3000, extent=40.0) for _ in range(4)]
    out = [None] * 4

    def run(k):
        out[k] = viscd.Detector().detect(scenes[k]).pairs

    threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(4):
        np.testing.assert_array_equal(out[k], brute_sphere_pairs(scenes[k]))


def test_help_teaches():
    doc = viscd.Detector.detect.__doc__
    for needle in ["(N, 4) float32", "(N, 6) float32", "(P, 2) uint32", "0 culled, 1 free, 2 colliding",
                   "without a copy", "ValueError", "PairCapError", "MemoryError", "Example"]:
        assert needle in doc, needle
    assert "lambda_" in viscd.Detector.__doc__ and "pair_memory_cap" in viscd.Detector.__doc__
    assert viscd.__doc__ and viscd.is_static.__doc__


def test_docstring_example_runs():
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(viscd.Detector.detect, "viscd.Detector.detect", globs={}):
        runner.run(test)
    assert runner.failures == 0 and runner.tries > 0


def test_config_round_trip():
    det = viscd.Detector("reference", lambda_=12.5, bits=32, layout="plain", culling=False, map_width=64,
                         map_height=32, shade=True, report_pixels=True, contact_events=True, pair_memory_cap=1 << 20,
                         threads=1, keep_order=False, simd="scalar", pixels_for_32_bits=10, pixels_for_64_bits=20,
                         follow_change=False, rest_margin=0.25, move_margin=2.5)
    assert det.backend == "reference"
    assert det.config == {"lambda_": 12.5, "pixels_for_32_bits": 10.0, "pixels_for_64_bits": 20.0, "bits": 32,
                          "layout": "plain", "culling": False, "map_width": 64, "map_height": 32, "shade": True,
                          "report_pixels": True, "contact_events": True, "pair_memory_cap": 1 << 20, "threads": 1,
                          "keep_order": False, "follow_change": False, "rest_margin": 0.25, "move_margin": 2.5,
                          "simd": "scalar"}
    assert viscd.Detector(**{"lambda": 7}).config["lambda_"] == 7.0
    assert viscd.Detector(bits="16", culling=np.bool_(False)).config["bits"] == 16
    det.set_config(bits="adaptive", lambda_=1)
    assert det.config["bits"] == "adaptive" and det.config["lambda_"] == 1.0
    assert det.memory_bytes >= 0 and "reference" in repr(det)


def test_stats_have_stage_times(rng):
    frame = viscd.Detector().detect(random_spheres(rng, 5000, extent=50.0))
    s = frame.stats
    assert set(s["stage_ms"]) == {"visibility", "count", "cull", "layout", "codes", "sort", "build", "fit",
                                  "query", "shade"}
    assert abs(s["total_ms"] - sum(s["stage_ms"].values())) < 1e-9
    assert s["detect_ms"] >= s["total_ms"] * 0.5 and s["bits"] in (16, 32, 64)
    assert "(" in s["layout"] and len(s["layout_axis_bits"]) == 3
    assert "5000 objects" in repr(frame)


def test_type_stub_follows_the_keyword_table():
    # The table in config_keywords.cpp is the one source: the stub's Detector.__init__ must list
    # the same keywords, in the same order, with the same defaults; Detector().config must hold
    # the non-gl ones with those defaults; the docstring must name every one.
    import ast
    import pathlib

    stub = pathlib.Path(viscd.__file__).with_name("__init__.pyi")
    tree = ast.parse(stub.read_text())
    detector = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Detector")
    init = next(n for n in detector.body if isinstance(n, ast.FunctionDef) and n.name == "__init__")
    stub_keywords = [(a.arg, ast.literal_eval(d)) for a, d in zip(init.args.kwonlyargs, init.args.kw_defaults)]
    table = viscd._viscd._keyword_table()
    assert [name for name, _ in stub_keywords] == [row[0] for row in table]
    defaults = viscd.Detector().config
    for (name, stub_default), (_, gl_only, _, literal) in zip(stub_keywords, table):
        assert stub_default == ast.literal_eval(literal), name
        assert name in viscd.Detector.__doc__, name
        if not gl_only:
            assert defaults[name] == stub_default, name
    assert set(defaults) == {row[0] for row in table if not row[1]}


def test_reads_during_a_frame_in_another_thread_raise(rng):
    # config, memory_bytes, static_count and static_kind read the detector: during another
    # thread's frame (GIL released) they raise as a call would, instead of racing with it.
    spheres = random_spheres(rng, 400_000, extent=600.0, r_min=0.05, r_max=0.5)
    det = viscd.Detector(threads=1)
    worker = threading.Thread(target=lambda: det.detect(spheres))
    refused = set()
    worker.start()
    while worker.is_alive():
        for name in ("config", "memory_bytes", "static_count", "static_kind"):
            try:
                getattr(det, name)
            except RuntimeError as e:
                assert "another thread" in str(e)
                refused.add(name)
    worker.join()
    assert refused, "no read ever met the running frame"
    assert det.memory_bytes > 0 and det.static_count == 0


def test_import_loads_no_mpi():
    """viscd.DistributedDetector is loaded on first use: importing viscd (even with *) starts no MPI."""
    import subprocess
    import sys

    code = "from viscd import *; import sys; assert 'mpi4py' not in sys.modules and 'viscd._viscd_mpi' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
