"""Anchoring new pairs to the model's texture: a known offset recovered from a synthetic image, and on real
renders of the arm, pairs formed on a wrong estimate anchored back onto the material point their feature shows;
several views' and parts' pairs refined and anchored in one batch as each alone."""

import math

import cv2
import numpy as np
import pytest
from scipy.ndimage import map_coordinates
from scipy.spatial import cKDTree

from tracker.abis.anchoring import AnchorSettings, observed_patches, texture_offsets
from tracker.abis.correspondences import pixel_jacobian, refine_surface_coordinates, surface_pixels
from tracker.abis.visibility import outward_normals
from tracker.models.dsq import PARAM_INDEX
from tracker.models.textures import block_noise_texture


@pytest.mark.parametrize("shift_px", [(0.0, 0.0), (0.6, -0.3), (1.6, -0.7), (-3.2, 2.4)])
def test_a_known_shift_of_the_material_is_recovered(shift_px):
    texture = cv2.cvtColor(
        block_noise_texture(np.random.default_rng(3), (10, 12), (200, 180, 150)), cv2.COLOR_RGB2GRAY
    ).astype(np.float32)
    jacobian = np.array([[30.0, -6.0], [4.0, 18.0]])  # pixels per radian of (eta, omega)
    to_surface = np.linalg.inv(jacobian)
    eta0, omega0, point = 0.3, -0.8, np.array([32.0, 32.0])
    # The image: pixel p + d shows the material the estimate puts at p + d + shift.
    ys, xs = np.mgrid[0:64, 0:64].astype(np.float64)
    d = np.stack([xs.ravel() - point[0] + shift_px[0], ys.ravel() - point[1] + shift_px[1]])
    eta, omega = eta0 + (to_surface @ d)[0], omega0 + (to_surface @ d)[1]
    rows = (math.pi / 2 - eta) / math.pi * texture.shape[0] - 0.5
    columns = ((omega + math.pi) / (2 * math.pi) * texture.shape[1] - 0.5) % texture.shape[1]
    image = map_coordinates(texture, [rows, columns], order=1, mode="nearest").reshape(64, 64).astype(np.float32)
    patches = observed_patches(image, point[None], AnchorSettings())
    offsets, trusted = texture_offsets(
        patches, np.array([eta0]), np.array([omega0]), jacobian[None], [texture], AnchorSettings()
    )
    assert trusted[0]
    np.testing.assert_allclose(jacobian @ offsets[0], shift_px, atol=0.15)
    if np.linalg.norm(shift_px) < 1:  # refining alone (a pair anchored before) finds a shift under a pixel
        offsets, _ = texture_offsets(
            patches,
            np.array([eta0]),
            np.array([omega0]),
            jacobian[None],
            [texture],
            AnchorSettings(),
            search=False,
        )
        np.testing.assert_allclose(jacobian @ offsets[0], shift_px, atol=0.15)


def test_pairs_formed_on_a_wrong_estimate_are_anchored_onto_their_material_point(arm, motion, rig, renderer):
    truth = motion.params(arm, 20)
    estimate = truth.copy()
    estimate[1, PARAM_INDEX["r2"]] += 0.03
    estimate[1, PARAM_INDEX["b1"]] += 0.015
    estimate = arm.connect(estimate)
    views = renderer.render(rig, arm.surface_meshes(truth))
    texture = cv2.cvtColor(arm.textures[1], cv2.COLOR_RGB2GRAY).astype(np.float32)
    grid, before, after = arm.sample_grid, [], []
    for camera in rig:
        gray = cv2.cvtColor(views[camera.name].rgb, cv2.COLOR_RGB2GRAY)
        corners = cv2.goodFeaturesToTrack(gray, 300, 0.01, 5).reshape(-1, 2).astype(np.float64)
        pixel = np.rint(corners).astype(int)
        points = corners[views[camera.name].labels[pixel[:, 1], pixel[:, 0]] == 2]
        if len(points) < 3:
            continue

        def on(params):
            world = arm.world_transforms(params)
            return lambda e, w: arm.part_points(params, 1, e, w, world)

        surface = on(estimate)
        world = arm.world_transforms(estimate)
        samples = surface(grid.eta, grid.omega)
        normals = outward_normals(surface, grid.eta, grid.omega, world[1][:3, 3])
        facing = np.flatnonzero(np.einsum("ij,ij->i", normals, camera.position - samples) > 0)
        _, nearest = cKDTree(camera.project(samples[facing])[0]).query(points)
        start = facing[nearest]
        pixels_at = surface_pixels([surface], [camera])
        eta, omega, distance = refine_surface_coordinates(
            pixels_at, grid.eta[start].copy(), grid.omega[start].copy(), points
        )
        keep = distance < 0.5
        eta, omega, points = eta[keep], omega[keep], points[keep]
        offsets, trusted = texture_offsets(
            observed_patches(gray.astype(np.float32), points, AnchorSettings()),
            eta,
            omega,
            pixel_jacobian(pixels_at, eta, omega),
            [texture],
            AnchorSettings(),
        )
        truly = on(truth)  # where the truth shows each pair's point: on its feature when the pair is right
        before.extend(np.linalg.norm(camera.project(truly(eta, omega))[0] - points, axis=1)[trusted])
        after.extend(
            np.linalg.norm(camera.project(truly(eta + offsets[:, 0], omega + offsets[:, 1]))[0] - points, axis=1)[
                trusted
            ]
        )
    assert len(before) >= 5
    assert np.median(before) > 1.2 and np.median(after) < 0.5 * np.median(before)


def test_pairs_of_several_views_and_parts_refine_and_anchor_in_one_batch_as_each_alone(arm, motion, rig, renderer):
    """The tracker refines and anchors every view's pairs at once: each view's and part's on its own gives the
    same (to rounding: a lone point's matmul may round another way)."""
    truth = motion.params(arm, 20)
    estimate = truth.copy()
    estimate[1, PARAM_INDEX["r2"]] += 0.03
    estimate = arm.connect(estimate)
    world = arm.world_transforms(estimate)
    surfaces = [lambda e, w, part=part: arm.part_points(estimate, part, e, w, world) for part in range(len(arm.parts))]
    views = renderer.render(rig, arm.surface_meshes(truth))
    textures = [cv2.cvtColor(texture, cv2.COLOR_RGB2GRAY).astype(np.float32) for texture in arm.textures]
    settings, rng = AnchorSettings(), np.random.default_rng(5)
    batch = {"parts": [], "views": [], "eta": [], "omega": [], "targets": [], "patches": []}
    for view, camera in enumerate(rig):
        gray = cv2.cvtColor(views[camera.name].rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
        for part in range(len(arm.parts)):
            n = 1 + 3 * part  # a lone point too
            eta, omega = rng.uniform(-1.2, 1.2, n), rng.uniform(-np.pi, np.pi, n)
            targets = camera.project(surfaces[part](eta, omega))[0] + rng.normal(0, 1.5, (n, 2))
            batch["parts"].append(np.full(n, part))
            batch["views"].append(np.full(n, view))
            for key, values in zip(("eta", "omega", "targets"), (eta, omega, targets), strict=True):
                batch[key].append(values)
            batch["patches"].append(observed_patches(gray, targets, settings))
    alone = []
    for parts, views_of, eta, omega, targets, patches in zip(*batch.values(), strict=True):
        pixels_at = surface_pixels([surfaces[parts[0]]], [rig[views_of[0]]])
        refined_eta, refined_omega, distance = refine_surface_coordinates(pixels_at, eta, omega, targets)
        jacobian = pixel_jacobian(pixels_at, refined_eta, refined_omega)
        offsets = texture_offsets(patches, refined_eta, refined_omega, jacobian, [textures[parts[0]]], settings)
        alone.append((refined_eta, refined_omega, distance, jacobian, *offsets))
    parts, views_of, eta, omega, targets, patches = (np.concatenate(values) for values in batch.values())
    pixels_at = surface_pixels(surfaces, list(rig), parts, views_of)
    refined_eta, refined_omega, distance = refine_surface_coordinates(pixels_at, eta, omega, targets)
    jacobian = pixel_jacobian(pixels_at, refined_eta, refined_omega)
    offsets = texture_offsets(patches, refined_eta, refined_omega, jacobian, textures, settings, texture_of=parts)
    batched = (refined_eta, refined_omega, distance, jacobian, *offsets)
    assert (distance < 0.5).sum() >= 10 and offsets[1].sum() >= 3  # most pairs settle, some anchor
    for got, expected in zip(batched, zip(*alone, strict=True), strict=True):
        np.testing.assert_allclose(got, np.concatenate(expected), rtol=0, atol=1e-9)
