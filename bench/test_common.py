"""Unit tests of bench/common.py (no binaries needed):  python3 -m unittest discover -s bench"""

from __future__ import annotations

import json
import os
import stat
import tempfile
import unittest
from pathlib import Path
from unittest import mock

import common


def runs(*rounds, prepare=0.0):
    """A contender's runs: one per round, trace ms as given (prepare fixed)."""
    return [dict(round=k + 1, prepare_ms=prepare, trace_ms=t, prepare_ms_runs=[prepare], trace_ms_runs=[t])
            for k, t in enumerate(rounds)]


def emb(threads, trace, prepare=0.0):
    return dict(kind="embree", threads=threads, runs=runs(*trace, prepare=prepare))


class RatioToEmbree(unittest.TestCase):
    def test_fastest_configuration_of_each_round(self):
        cs = {"embree-medium-1t": emb(1, [10, 10, 10]), "embree-low-1t": emb(1, [12, 5, 12]),
              "bvh-1t": dict(kind="raysift", threads=1, runs=runs(20, 20, 30))}
        r = common.ratio_to_embree(cs, "bvh-1t", "trace")
        # per round: 20/10, 20/5, 30/10 -> median 3 (MEDIUM, the faster by median, fixed for every
        # round: 2, 2, 3 -> median 2, the rule before the shared module)
        self.assertEqual(r["median"], 3.0)
        self.assertEqual(r["max"], 4.0)
        self.assertEqual(r["rounds"], 3)
        self.assertEqual(r["vs"], "embree-medium-1t")
        self.assertEqual(r["best"], {"embree-medium-1t": 2, "embree-low-1t": 1})

    def test_same_threads_only_and_frame(self):
        cs = {"embree-low-1t": emb(1, [1, 1], prepare=1), "embree-low-2t": emb(2, [2, 2], prepare=2),
              "dacrt-2t": dict(kind="raysift", threads=2, runs=runs(6, 6, prepare=2))}
        self.assertEqual(common.ratio_to_embree(cs, "dacrt-2t", "frame")["median"], 2.0)  # (2+6)/(2+2)
        self.assertEqual(common.ratio_to_embree(cs, "dacrt-2t", "frame", embree_metric="trace")["median"], 4.0)

    def test_rounds_pair_by_number(self):
        slow = runs(8, 8, 8)  # a slow contender measured in 3 of 5 rounds
        cs = {"embree-medium-1t": emb(1, [4, 4, 4, 1, 1]), "x-1t": dict(kind="raysift", threads=1, runs=slow)}
        r = common.ratio_to_embree(cs, "x-1t")
        self.assertEqual((r["median"], r["rounds"]), (2.0, 3))

    def test_no_embree(self):
        cs = {"bvh-1t": dict(kind="raysift", threads=1, runs=runs(1))}
        self.assertIsNone(common.ratio_to_embree(cs, "bvh-1t"))

    def test_first_run(self):
        c = dict(runs=[dict(prepare_ms=1, trace_ms=2, prepare_ms_runs=[5, 1], trace_ms_runs=[7, 2])])
        self.assertEqual(common.round_values(c, "frame", "first"), {1: 12.0})
        self.assertEqual(common.round_values(c, "frame"), {1: 3.0})


class Reports(unittest.TestCase):
    def test_work_counters_today(self):
        j = {"tracer": "bvh", "stats": {"ray_box": 5, "ray_tri": 2, "trace_ms": 1.5, "rays": 9, "peak_bytes": 3}}
        self.assertEqual(common.work_counters(j), {"ray_box": 5, "ray_tri": 2})

    def test_work_counters_typed(self):
        self.assertEqual(common.work_counters({"stats": {"work": {"ray_box": 5}, "trace_ms": 1}}), {"ray_box": 5})
        j = {"tracer": "dacrt", "stats": {"work": {"dacrt": {"cone_box": 3, "ray_tri": 4}}}}
        self.assertEqual(common.work_counters(j), {"cone_box": 3, "ray_tri": 4})
        self.assertEqual(common.work_counters({"hits": 1}), {})

    def test_report_times(self):
        t = common.report_times({"prepare_ms": 2, "trace_ms": 3, "hits": 4, "trace_ms_runs": [9, 3],
                                 "prepare_ms_runs": [8, 2]})
        self.assertEqual((t["prepare_ms"], t["trace_ms"], t["trace_ms_runs"]), (2.0, 3.0, [9.0, 3.0]))


class Tracers(unittest.TestCase):
    def fake(self, script):
        d = tempfile.mkdtemp()
        p = Path(d) / "raysift"
        p.write_text("#!/bin/sh\n" + script)
        p.chmod(p.stat().st_mode | stat.S_IEXEC)
        return p

    def test_text_fallback(self):
        p = self.fake('[ "$2" = "--json" ] && { echo "unexpected argument" >&2; exit 2; }\n'
                      'printf "naive\\nbvh   SAH BVH\\ndacrt\\n"\n')
        self.assertEqual(common.list_tracers(p), ["naive", "bvh", "dacrt"])

    def test_json(self):
        for out in (["bvh", "new"], [{"name": "bvh"}, {"name": "new"}], {"tracers": [{"name": "bvh"}, {"name": "new"}]}):
            p = self.fake(f"echo '{json.dumps(out)}'\n")
            self.assertEqual(common.list_tracers(p), ["bvh", "new"])


class ScenesAndNames(unittest.TestCase):
    def test_scenes_dir(self):
        with mock.patch.dict(os.environ, {"RAYSIFT_SCENES": "/env"}):
            self.assertEqual(common.scenes_dir("/arg"), Path("/arg"))
            self.assertEqual(common.scenes_dir(None), Path("/env"))
        with mock.patch.dict(os.environ, {}, clear=True):
            self.assertEqual(common.scenes_dir(None), common.DEFAULT_SCENES_DIR)

    def test_resolve(self):
        with tempfile.TemporaryDirectory() as d:
            (Path(d) / "a.ply").write_text("")
            got = common.resolve_scenes(["a.ply", "sphere:10", "cornell", "bun_zipper.ply", "nope.obj"], Path(d))
            self.assertEqual(got, [str((Path(d) / "a.ply").resolve()), "sphere:10", "cornell", "sphere:65536"])

    def test_names(self):
        self.assertEqual(common.contender_name("bvh", 2), "bvh-2t")
        self.assertEqual(common.embree_name("low", 1), "embree-low-1t")
        self.assertEqual(common.split_name("embree-low-1t"), ("embree-low", 1))
        self.assertEqual(common.order_names(["bvh-2t", "bvh-1t", "embree-low-1t"]),
                         ["embree-low-1t", "bvh-1t", "bvh-2t"])

    def test_tracer_variants(self):
        self.assertEqual(common.tracer_args("bvh"), ["--tracer", "bvh"])
        self.assertEqual(common.tracer_args("dacrt:top_below=0+leaf_pairs=9"),
                         ["--tracer", "dacrt", "--opt", "top_below=0", "--opt", "leaf_pairs=9"])
        self.assertEqual(common.tracer_base("dacrt:top_below=0"), "dacrt")
        self.assertEqual(common.choose_tracers(["bvh", "dacrt"], "dacrt:top_below=0,bvh"),
                         ["dacrt:top_below=0", "bvh"])
        with self.assertRaises(SystemExit):
            common.choose_tracers(["bvh"], "dacrt:top_below=0")
        self.assertTrue(common.over_budget("naive:x=1", 1e9, 1e9))
        self.assertEqual(common.split_name(common.contender_name("dacrt:top_below=0", 2)),
                         ("dacrt:top_below=0", 2))

    def test_camera(self):
        self.assertEqual(common.camera_args(common.camera_preset("/x/sponza.obj.gz")),
                         ["--eye=-13,2.5,0", "--look=10,4.5,0", "--up=0,1,0", "--fov", "60"])
        self.assertEqual(common.camera_args(common.camera_preset("bun_zipper.ply")), [])
        self.assertEqual(common.slug("tile:2:/a/dragon.ply.gz"), "tile2x2_dragon.ply.gz")


if __name__ == "__main__":
    unittest.main()
