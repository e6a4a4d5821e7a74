"""Ray casting: this project's NumPy BVH against Blender's BVHTree and Embree, in one run.

For each scene (the Cornell box, an ~80k and a ~1M triangle mesh from bench/meshes.py) and each
ray set (coherent pinhole-camera rays, incoherent rays with random origins in the scene's box and
uniformly random directions) it measures closest-hit rays per second of

* `bvh`:         kernels/bvh.py with its default settings (one thread per core),
* `bvh_1t`:      the same BVH on one thread,
* `bvhtree`:     `mathutils.bvhtree.BVHTree.ray_cast` called in a Python loop (one thread),
* `embree`:      Embree through `embreex` (`EmbreeScene.run`, a loop over rtcIntersect1: one thread),

alternately, best of `--repeats`, and the build time of each structure. The BVHTree loop runs on
every camera ray and on the first `--bvhtree-rays` random rays (a random sample: its rate does not
depend on the count; a block of camera rays would be a block of image rows). It also checks
that the three agree on which rays hit (Embree is not watertight, so a handful may differ).

With --loaded (bench/rays_loaded.py) every contender runs beside a second process that keeps
one core busy (`BUSY`, NumPy arithmetic on a cache-sized array), as on a machine shared with
other work: the BVH's threads then share a core with it, and `thread_choice.py` has to notice.

Usage:  .venv/bin/python bench/rays.py [--quick] [--rays N] [--repeats K] [--loaded]
Writes out/bench/rays.json (rays_loaded.json with --loaded); `ratios` hold
bvh_vs_bvhtree_rays_per_s/..., bvh_vs_embree_rays_per_s/...
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import meshes  # noqa: E402
from _report import format_table, timed, versions, write_report  # noqa: E402

from classic_bake.kernels.geometry.bvh import BVH, BVHSettings  # noqa: E402

CAMERA_FOV_DEG = 39.3  # the Cornell box camera's field of view; used for every scene
# The second process of --loaded: one core kept busy by NumPy arithmetic on 512 KB (in the core's
# L2 cache, so it takes a core, not the memory bus), until the bench stops it.
BUSY = ("import numpy as np\n"
        "x = np.random.default_rng(0).random(1 << 16)\n"
        "while True:\n"
        "    np.sqrt(x, out=x)\n"
        "    x += 1.0\n")


def camera_rays(eye, target, up, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole rays through the pixel centres of a size x size image: (R, 3) float32 each."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    half = np.tan(np.radians(CAMERA_FOV_DEG) / 2)
    s = (np.arange(size) + 0.5) / size * 2 - 1
    ys, xs = np.meshgrid(-s, s, indexing="ij")  # row 0 at the top
    d = forward + half * (xs[..., None] * right + ys[..., None] * true_up)
    d = d.reshape(-1, 3)
    o = np.broadcast_to(eye, d.shape)
    return o.astype(np.float32), d.astype(np.float32)


def random_rays(tris: np.ndarray, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Origins uniform in the scene's bounding box, directions uniform on the sphere."""
    rng = np.random.default_rng(seed)
    pts = tris.reshape(-1, 3)
    o = rng.uniform(pts.min(0), pts.max(0), (count, 3))
    d = rng.normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o.astype(np.float32), d.astype(np.float32)


def ray_sets(name: str, tris: np.ndarray, count: int, image: int) -> dict[str, tuple]:
    """The coherent and incoherent ray sets of a scene."""
    if name.startswith("cornell"):
        # The published camera, in Blender's frame: (x, y, z) -> (-x, z, y), mm -> m.
        eye, target = (-0.278, -0.8, 0.273), (-0.278, 0.0, 0.273)
    else:
        eye, target = (0.4, -3.6, 1.2), (0.0, 0.0, 0.0)
    return {
        "camera": camera_rays(eye, target, (0, 0, 1), image),
        "random": random_rays(tris, count, seed=len(tris)),
    }


class BlenderTree:
    """mathutils.bvhtree.BVHTree over the triangles (None where bpy is missing)."""

    def __init__(self, tris: np.ndarray):
        from mathutils.bvhtree import BVHTree

        verts = tris.reshape(-1, 3).astype(np.float64).tolist()
        polys = np.arange(len(verts)).reshape(-1, 3).tolist()
        start = time.perf_counter()
        self.tree = BVHTree.FromPolygons(verts, polys, all_triangles=True)
        self.build_s = time.perf_counter() - start

    def cast(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Triangle index per ray (-1 on a miss), by ray_cast in a loop."""
        cast = self.tree.ray_cast
        ol, dl = o.astype(np.float64).tolist(), d.astype(np.float64).tolist()
        hits = [cast(a, b)[2] for a, b in zip(ol, dl, strict=True)]
        return np.array([-1 if h is None else h for h in hits])


class EmbreeTree:
    """An Embree scene through embreex."""

    def __init__(self, tris: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        start = time.perf_counter()
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, tris.astype(np.float32))
        # The scene commits (builds its BVH) on the first query.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
        self.build_s = time.perf_counter() - start

    def cast(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        return np.asarray(self.scene.run(o, d))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small meshes and ray counts")
    parser.add_argument("--rays", type=int, default=500_000, help="incoherent rays per scene")
    parser.add_argument("--image", type=int, default=512, help="camera image side, pixels")
    parser.add_argument("--bvhtree-rays", type=int, default=100_000,
                        help="random rays given to the BVHTree loop (camera rays: all)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--threads", type=int, default=0, help="BVH threads (0: one per core)")
    parser.add_argument("--loaded", action="store_true",
                        help="run beside a CPU-bound process; writes rays_loaded.json")
    args = parser.parse_args(argv)
    if args.quick:
        args.rays, args.image, args.bvhtree_rays, args.repeats = 50_000, 128, 10_000, 1
    if not args.loaded:
        return measure(args)
    busy = subprocess.Popen([sys.executable, "-c", BUSY])
    try:
        time.sleep(1.0)  # the second process running before the first measurement
        return measure(args)
    finally:
        busy.kill()
        busy.wait()


def measure(args: argparse.Namespace) -> int:
    """Every scene and ray set against every contender; writes the report."""

    try:
        import bpy  # noqa: F401  (makes mathutils importable)

        have_bpy = True
    except ImportError:
        have_bpy = False

    settings = BVHSettings(threads=args.threads)
    one_thread = BVHSettings(threads=1)
    rows, ratios, figures = [], {}, {}
    for name, tris in meshes.benchmark_meshes(full=not args.quick).items():
        build = {}
        start = time.perf_counter()
        bvh = BVH.build(tris, settings)
        build["bvh"] = time.perf_counter() - start
        bvh_1t = BVH(bvh._prepared, bvh._tree, one_thread)
        embree = EmbreeTree(tris)
        build["embree"] = embree.build_s
        blender = BlenderTree(tris) if have_bpy else None
        build["bvhtree"] = blender.build_s if blender else float("nan")
        for kind, (o, d) in ray_sets(name, tris, args.rays, args.image).items():
            case = f"{name}/{kind}"
            # The BVHTree loop is slow, so it gets a sample of the rays: the first of the random
            # ones (a random sample), but every camera ray: the first image rows are mostly sky
            # and would flatter it (1M torus: 13% of the first 100k rays hit, 45% of all).
            n_bt = len(o) if kind == "camera" else min(args.bvhtree_rays, len(o))
            runs = {
                "bvh": (bvh.intersect, o, d),
                "embree": (embree.cast, o, d),
                "bvh_1t": (bvh_1t.intersect, o, d),
            }
            if blender:
                runs["bvhtree"] = (blender.cast, o[:n_bt], d[:n_bt])
            times = dict.fromkeys(["bvh", "bvh_1t", "embree", "bvhtree"], np.inf)
            for _ in range(args.repeats):  # alternate the contenders, keep each one's best
                for key, (fn, *inputs) in runs.items():
                    times[key] = min(times[key], timed(fn, *inputs))
            rate = {k: len(o) / t for k, t in times.items()}
            rate["bvhtree"] = n_bt / times["bvhtree"] if blender else float("nan")
            ours = bvh.intersect(o, d).tri
            agree_embree = float(np.mean(ours == embree.cast(o, d)))
            agree_bvhtree = (
                float(np.mean(ours[:n_bt] == blender.cast(o[:n_bt], d[:n_bt])))
                if blender
                else float("nan")
            )
            ratios[f"bvh_vs_bvhtree_rays_per_s/{case}"] = rate["bvh"] / rate["bvhtree"]
            ratios[f"bvh_1t_vs_bvhtree_rays_per_s/{case}"] = rate["bvh_1t"] / rate["bvhtree"]
            ratios[f"bvh_vs_embree_rays_per_s/{case}"] = rate["bvh"] / rate["embree"]
            ratios[f"bvh_1t_vs_embree_rays_per_s/{case}"] = rate["bvh_1t"] / rate["embree"]
            figures[case] = {
                "triangles": len(tris),
                "rays": len(o),
                "hit_fraction": float(np.mean(ours >= 0)),
                "rays_per_s": rate,
                "build_s": build,
                "same_triangle_as_embree": agree_embree,
                "same_triangle_as_bvhtree": agree_bvhtree,
            }
            rows.append(
                [
                    case,
                    len(tris),
                    f"{build['bvh']:.2f}/{build['bvhtree']:.2f}/{build['embree']:.2f}",
                    rate["bvh"] / 1e6,
                    rate["bvh_1t"] / 1e6,
                    rate["bvhtree"] / 1e6,
                    rate["embree"] / 1e6,
                    rate["bvh"] / rate["bvhtree"],
                    rate["bvh"] / rate["embree"],
                    f"{agree_embree:.4f}",
                ]
            )
            print(f"  {case}: done", file=sys.stderr, flush=True)
    header = [
        "case",
        "tris",
        "build s bvh/bvhtree/embree",
        "bvh Mray/s",
        "bvh 1t",
        "bvhtree",
        "embree",
        "bvh/bvhtree",
        "bvh/embree",
        "agree embree",
    ]
    print(format_table(header, rows))
    figures["settings"] = {
        "bvh": repr(settings),
        "threads_used": settings.thread_count,
        "incoherent_rays": args.rays,
        "camera_image": args.image,
        "bvhtree_rays": args.bvhtree_rays,
        "beside": "a CPU-bound process (bench/rays.py BUSY)" if args.loaded else "nothing",
    }
    name = "rays_loaded" if args.loaded else "rays"
    path = write_report(name, ratios, figures, versions("bpy", "embreex"))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
