"""The randomised stereo sphere scene family (issue 15): determinism, ranges, ground truth, textures."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest

from tudorvision.lab.scene_family import (RANGES, apparent_radius_px, photo_texture_paths, render_family_scene,
                                          sample_family, sample_scene_params)
from tudorvision.sim.camera import intrinsic_matrix, look_at
from tudorvision.sim.lighting import AmbientLight, DirectionalLight
from tudorvision.sim.raycast import render_gbuffer
from tudorvision.sim.shapes import Scene, Sphere
from tudorvision.sim.specular import specular_radiance
from tudorvision.sim.textures import TexturedRectangle, load_texture_crop, procedural_texture

REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"


def _in(value, key):
    lo, hi = RANGES[key]
    return lo <= value <= hi


def test_family_is_deterministic_for_a_seed_and_differs_between_seeds():
    a, b = sample_family(7, 5, textures=[]), sample_family(7, 5, textures=[])
    assert [asdict(p) for p in a] == [asdict(p) for p in b]
    c = sample_family(8, 5, textures=[])
    assert [p.sphere_radius_m for p in a] != [p.sphere_radius_m for p in c]


def test_parameters_fall_in_the_stated_ranges():
    fam = sample_family(0, 300, textures=["a.png", "b.png"])
    for p in fam:
        assert _in(p.sphere_radius_m, "sphere_radius_m") and _in(p.distance_m, "distance_m")
        assert _in(p.f_px, "f_px") and _in(p.specular_strength, "specular_strength") and _in(p.shininess, "shininess")
        assert _in(p.wb_gains[0], "wb_gain") and _in(p.wb_gains[2], "wb_gain") and p.wb_gains[1] == 1.0
        assert _in(p.exposure_gain, "exposure_gain") and _in(p.full_well_e, "full_well_e")
        assert _in(p.read_noise_e, "read_noise_e")
        assert p.jpeg_quality is None or _in(p.jpeg_quality, "jpeg_quality")
        assert 0 < p.baseline_m <= min(3.0, RANGES["baseline_ratio"][1] * p.distance_m) + 1e-12
        assert p.texture_source == "photo" and set(p.texture_files) <= {"a.png", "b.png"}
    # every part of the ranges is visited: radii and distances spread over their interval
    radii = np.array([p.sphere_radius_m for p in fam])
    assert radii.min() < 0.02 and radii.max() > 0.045
    assert 0.1 < np.mean([p.occluded_sphere is not None for p in fam]) < 0.5
    assert 0.6 < np.mean([p.jpeg_quality is not None for p in fam]) < 0.95


def test_family_rejects_a_bad_size():
    with pytest.raises(ValueError, match="n: expected a positive integer"):
        sample_family(0, 0)


def test_rendered_sample_has_each_sphere_where_the_truth_says():
    params = sample_scene_params(np.random.default_rng(11), textures=[])
    params = type(params)(**{**asdict(params), "occluded_sphere": None, "jpeg_quality": None})
    scene = render_family_scene(params)
    assert "procedural" in scene.note
    for cam_name in scene.cameras:
        img = scene.frames[cam_name].astype(float)
        for s, colour in (("red", 2), ("green", 1)):
            u, v = scene.uv_true[cam_name][s]
            r = scene.radius_px[cam_name][s]
            assert 1.0 < r < 200.0
            # the pixel at the true centre is dominated by the sphere's colour channel
            px = img[int(round(v)), int(round(u))]
            assert px[colour] > px[[c for c in range(3) if c != colour]].max()
            # the true 3D centre is in front of the left camera, at about the drawn distance
            assert 1.0 < scene.centers_left[s][2] < params.distance_m + 1.0
    # true 3D centres are 0.16 m apart (the end-effector bar)
    assert abs(np.linalg.norm(scene.centers_left["red"] - scene.centers_left["green"]) - 0.16) < 1e-6


def test_static_frames_are_the_same_view_with_their_own_noise():
    """More frames of a static set-up: the first frames unchanged, the extra ones the same image up to noise."""
    params = sample_scene_params(np.random.default_rng(11), textures=[])
    params = type(params)(**{**asdict(params), "jpeg_quality": None})
    plain, more = render_family_scene(params), render_family_scene(params, static_frames=3)
    assert plain.static_frames == () and len(more.static_frames) == 3
    for cam in ("left", "right"):
        assert np.array_equal(plain.frames[cam], more.frames[cam])          # their own random stream
        assert np.array_equal(plain.pick_frames[cam], more.pick_frames[cam])
        ref = more.frames[cam].astype(float)
        # the pick frame is the same view with independent noise: the extra frames differ from the tracking frame
        # as much as it does, and from each other
        noise = np.abs(more.pick_frames[cam].astype(float) - ref).mean()
        extra = [f[cam].astype(float) for f in more.static_frames]
        for a in extra:
            assert 0.5 * noise < np.abs(a - ref).mean() < 2.0 * noise
        assert not np.array_equal(extra[0], extra[1])
        # averaging frames averages the noise: the mean of the four frames is nearer the pick frame's view
        pick = more.pick_frames[cam].astype(float)
        assert np.abs(np.mean([ref, *extra], axis=0) - pick).mean() < np.abs(ref - pick).mean()


def test_truth_matches_the_ray_cast_silhouette_centroid():
    """Oracle: the exact silhouette centroid against the first moment of the ray-cast sphere mask."""
    params = sample_scene_params(np.random.default_rng(5), textures=[])
    params = type(params)(**{**asdict(params), "occluded_sphere": None, "f_px": 1400.0, "distance_m": 1.6,
                             "sphere_radius_m": 0.04, "aim_offset_m": (0.0, 0.0, 0.0)})
    scene = render_family_scene(params)
    from tudorvision.sim.scenes import arm_geometry_from_joints
    centres = arm_geometry_from_joints(params.theta_rad).sphere_centers_base
    cam = scene.cameras["left"]
    for s in ("red", "green"):
        shape = Sphere(center=centres[s], radius=params.sphere_radius_m)
        gb = render_gbuffer(cam, Scene(static=[shape], lights=[AmbientLight()]))
        vv, uu = np.nonzero(gb.object_id == 1)
        assert np.hypot(uu.mean() - scene.uv_true["left"][s][0], vv.mean() - scene.uv_true["left"][s][1]) < 0.1
        assert abs(np.sqrt(uu.size / np.pi) - scene.radius_px["left"][s]) < 0.05 * scene.radius_px["left"][s] + 0.5


def test_apparent_radius_oracle():
    cam = look_at([0, -3, 0], [0, 0, 0], K=intrinsic_matrix(500, 99.5, 99.5), width=200, height=200)
    assert apparent_radius_px(cam, [0, 0, 0], 0.03) == pytest.approx(500 * np.arcsin(0.01), rel=1e-12)


def test_textured_rectangle_tiles_the_texture():
    tex = np.random.default_rng(0).uniform(0, 1, (4, 8, 3))
    r = TexturedRectangle(texture_rgb=tex, texture_size_m=(2.0, 1.0), half_size=(2.0, 1.0))
    # (-u, -v) corner is texel (0, 0); one texture every 2 m along u
    pts = np.array([[-1.99, -0.99, 0.0], [0.01, -0.99, 0.0], [-1.99 + 0.25, -0.99 + 0.25, 0.0]])
    a = r.albedo(pts)
    np.testing.assert_allclose(a[0], tex[0, 0])
    np.testing.assert_allclose(a[1], tex[0, 0])
    np.testing.assert_allclose(a[2], tex[1, 1])
    with pytest.raises(ValueError, match="texture_rgb"):
        TexturedRectangle(texture_rgb=np.full((2, 2, 3), 2.0))


def test_photo_textures_load_or_fall_back(tmp_path):
    rng = np.random.default_rng(0)
    paths = photo_texture_paths()
    if REALDATA.is_dir():
        assert paths, "realdata present but no photo found"
        tex = load_texture_crop(paths[0], rng)
        assert tex.ndim == 3 and tex.shape[2] == 3 and 0.0 <= tex.min() and tex.max() <= 1.0
        assert tex.std() > 0.01   # a photograph, not a flat colour
    assert photo_texture_paths(tmp_path) == []
    p = sample_scene_params(rng, textures=photo_texture_paths(tmp_path))
    assert p.texture_source == "procedural"
    tex = procedural_texture(rng, 32)
    assert tex.shape == (32, 32, 3) and tex.std() > 0.005
    with pytest.raises(ValueError, match="cannot read"):
        load_texture_crop(tmp_path / "missing.png", rng)


def test_specular_peaks_at_the_mirror_direction():
    """Oracle: the highlight of a directional light sits where the normal bisects light and view."""
    cam = look_at([0, -3, 0], [0, 0, 0], K=intrinsic_matrix(400, 99.5, 99.5), width=200, height=200)
    light_dir = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)          # rays travel +x +y
    scene = Scene(static=[Sphere(center=(0, 0, 0), radius=0.5)],
                  lights=[DirectionalLight(direction_world=light_dir, intensity=1.0)])
    spec = specular_radiance(cam, render_gbuffer(cam, scene), scene.lights, [1], strength=1.0, shininess=400)
    v, u = np.unravel_index(spec[..., 0].argmax(), spec.shape[:2])
    h = -light_dir + np.array([0.0, -1.0, 0.0])
    h /= np.linalg.norm(h)
    p = 0.5 * h    # surface point with normal h (camera far enough for the view ray to be ~ -y)
    from tudorvision.sim.camera import project_points
    uv = project_points(cam, p[None])[0]
    assert np.hypot(u - uv[0], v - uv[1]) < 3.0
    assert spec[..., 0].max() == pytest.approx(1.0, abs=0.05)
    with pytest.raises(ValueError, match="shininess"):
        specular_radiance(cam, render_gbuffer(cam, scene), scene.lights, [1], strength=1.0, shininess=0)


def test_sphere_masks_are_what_is_seen_of_each_sphere():
    """``sphere_masks``: a sphere's mask lies within its own silhouette (the sphere ray-cast alone) and is most of
    it; with the occluder in front of one sphere, that sphere's mask loses pixels and the other's does not."""
    base = sample_scene_params(np.random.default_rng(5), textures=[])
    base = type(base)(**{**asdict(base), "f_px": 1400.0, "distance_m": 1.6, "sphere_radius_m": 0.04,
                         "aim_offset_m": (0.0, 0.0, 0.0)})
    clear = render_family_scene(type(base)(**{**asdict(base), "occluded_sphere": None}))
    hidden = render_family_scene(type(base)(**{**asdict(base), "occluded_sphere": "red"}))
    from tudorvision.sim.scenes import arm_geometry_from_joints
    centres = arm_geometry_from_joints(base.theta_rad).sphere_centers_base
    for cam in ("left", "right"):
        for s in ("red", "green"):
            m = clear.sphere_masks[cam][s]
            assert m.shape == clear.frames[cam].shape[:2] and m.dtype == bool
            alone = render_gbuffer(clear.cameras[cam], Scene(static=[Sphere(center=centres[s],
                                                                            radius=base.sphere_radius_m)],
                                                             lights=[AmbientLight()])).object_id == 1
            assert not (m & ~alone).any() and m.sum() > 0.5 * alone.sum()
        assert hidden.sphere_masks[cam]["red"].sum() < clear.sphere_masks[cam]["red"].sum()
        assert np.array_equal(hidden.sphere_masks[cam]["green"], clear.sphere_masks[cam]["green"])
