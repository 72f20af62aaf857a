"""A 20-frame animation through set_transform (and a deformation through set_vertices): every
frame, every tracer's closest hits and occlusion equal naive's bit for bit, and the tracers
update (BVH refit, DACRT re-read) instead of being made anew."""

import numpy as np

import raysift

FRAMES = 20


def soup_of(spec):
    """A generator's world triangles as an indexed mesh (vertices, faces)."""
    tris = raysift.Scene.load(spec).triangles().astype(np.float64)
    return tris.reshape(-1, 3), np.arange(len(tris) * 3).reshape(-1, 3)


def rotation(axis, angle, translation):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    m[:3, 3] = translation
    return m


def shadow_rays(scene, hits, rays, light):
    """Segments from each camera hit towards the light (t in [1e-4, 1])."""
    hit = hits["primitive_ids"].reshape(-1) != raysift.MISS
    r = rays.reshape(-1, 8)[hit]
    p = r[:, :3] + r[:, 3:6] * hits["t_hit"].reshape(-1)[hit][:, None]
    out = np.empty((len(p), 8), np.float32)
    out[:, :3] = p
    out[:, 3:6] = light - p
    out[:, 6], out[:, 7] = 1e-4, 1.0
    return out


def test_twenty_frames_equal_naive():
    scene = raysift.Scene()
    sphere = scene.add_triangles(*soup_of("sphere:1280"), name="sphere")
    soup = scene.add_triangles(*soup_of("soup:600:3"), name="soup")
    floor = scene.add_triangles([[-4, -1.5, -4], [4, -1.5, -4], [4, -1.5, 4], [-4, -1.5, 4]],
                                [[0, 1, 2], [0, 2, 3]], name="floor")
    ring_v, ring_f = soup_of("sphere:320")
    ring = scene.add_triangles(ring_v * [1.0, 0.2, 1.0], ring_f, name="flat sphere")
    rays = scene.camera_rays(40, 30, eye=(0, 1.0, 7.0), look=(0, 0, 0), fov=60)
    light = np.array([3.0, 6.0, 4.0], np.float32)
    tracers = [("bvh", {}), ("bvh", {"update": "refit"}), ("bvh", {"update": "auto"}), ("dacrt", {})]
    refits = 0
    for k in range(FRAMES):
        a = 2 * np.pi * k / FRAMES
        scene.set_transform(sphere, rotation([0, 1, 0], a, [1.5 * np.cos(a), 0, 1.5 * np.sin(a)]))
        scene.set_transform(soup, rotation([1, 1, 0], -a, [-1.0, 0.3 * np.sin(3 * a), 0]))
        scene.set_transform(ring, rotation([0, 0, 1], 0.5 * a, [0, 1.2, -0.5]))
        if k % 5 == 4:  # a deformation now and then
            scene.set_vertices(ring, ring_v * [1.0, 0.2 + 0.05 * k, 1.0])
        if k == 10:
            scene.set_transform(floor, rotation([1, 0, 0], 0.1, [0, -0.2, 0]))
        want = scene.cast_rays(rays, tracer="naive")
        hits = (want["primitive_ids"] != raysift.MISS).sum()
        assert hits > 300, f"frame {k}: the camera sees the scene"
        shadow = shadow_rays(scene, want, rays, light)
        want_occ = scene.test_occlusions(shadow, tracer="naive")
        assert 0 < want_occ.sum() < len(want_occ), f"frame {k}: some shadow rays are blocked"
        for name, opts in tracers:
            got = scene.cast_rays(rays, tracer=name, **opts)
            prep = scene.last_stats["prepare"]
            assert prep is not None, f"frame {k}: {name} {opts} prepared for the changed scene"
            if k > 0 and opts.get("update") == "refit":
                assert prep["built"]["builds"] == 0 and prep["built"]["refitted"] > 0, prep
                refits += 1
            for key in want:
                np.testing.assert_array_equal(
                    got[key].view(np.uint32) if got[key].dtype == np.float32 else got[key],
                    want[key].view(np.uint32) if want[key].dtype == np.float32 else want[key],
                    err_msg=f"frame {k}: {name} {opts}: {key}")
            occ = scene.test_occlusions(shadow, tracer=name, **opts)
            assert scene.last_stats["prepare"] is None, "same scene: no second prepare"
            np.testing.assert_array_equal(occ, want_occ, err_msg=f"frame {k}: {name} {opts}: occlusion")
    assert refits == FRAMES - 1
    assert scene.version == 3 * FRAMES + FRAMES // 5 + 1
