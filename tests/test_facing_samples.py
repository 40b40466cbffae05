"""A closed mesh's first picture that culls back faces samples only what faces its eye (View.sample's
``facing``, surface_splats' ``facing_eye``): the kept splats equal those of the whole sampling, the
picture equals the whole surface's, and another camera gets the whole surface.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import surfsplat
from surfsplat import CameraSpec, RenderOptions, VisibilityOptions
from surfsplat.geometry.sampling import facing_samples, surface_splats
from surfsplat.io.mesh import Mesh

pytestmark = pytest.mark.gl

EYE = (1.3, 0.9, 3.1)
OTHER = (-2.6, -1.2, -1.9)


def box(inward: bool = False) -> Mesh:
    """A closed box with sharp edges (clip lines); ``inward``: wound inside out."""
    s = trimesh.creation.box((1.0, 0.8, 0.6))
    faces = s.faces[:, ::-1] if inward else s.faces
    return Mesh(np.asarray(s.vertices, np.float32), np.asarray(faces, np.int64))


@pytest.mark.parametrize("inward", [False, True])
def test_facing_samples_are_the_whole_samplings_facing_ones(inward):
    """Kept splats equal the whole sampling's at the same rows (normals turned outward, as
    outward_splats turns the whole cloud), and every dropped one faces away from the eye."""
    mesh = box(inward)
    whole = surface_splats(mesh, 30_000, sharp_angle=30.0)
    keep, flip = facing_samples(whole, EYE)
    assert flip == inward
    part = surface_splats(mesh, 30_000, sharp_angle=30.0, facing_eye=EYE)
    assert 0.3 < keep.mean() < 0.7 and len(part) == keep.sum()
    sign = -1.0 if inward else 1.0
    for name in ("positions", "u", "v", "clip_lines"):
        assert np.array_equal(getattr(part, name), getattr(whole, name)[keep]), name
    assert np.array_equal(part.normals, sign * whole.normals[keep])
    to_eye = np.asarray(EYE) - whole.positions[~keep]
    assert (np.einsum("ij,ij->i", sign * whole.normals[~keep], to_eye) < 0).all()


def test_first_picture_samples_what_faces_the_eye_and_another_camera_the_whole_surface():
    """The first ewa picture from outside draws about half the samples, and equals (within float
    summation order) the picture of the whole surface; a second camera resamples the whole surface
    once, and its picture equals that of a view that sampled the whole surface."""
    mesh = box()
    eye, other = (CameraSpec(eye=e, target=(0.0, 0.0, 0.0)) for e in (EYE, OTHER))
    first = surfsplat.prepare(mesh)
    a = first.render(eye, width=96, height=80)
    whole = surfsplat.prepare(mesh)
    whole.sample(whole.camera(eye, 96, 80))   # the whole surface, for this camera's density
    b = whole.render(eye, width=96, height=80)
    assert 0.3 * b.splats < a.splats < 0.7 * b.splats
    assert np.abs(a.frame.color - b.frame.color).max() < 1e-4
    assert np.array_equal(a.frame.alpha > 0, b.frame.alpha > 0)
    c = first.render(other, width=96, height=80)
    d = whole.render(other, width=96, height=80)
    assert c.splats == d.splats == b.splats
    assert np.abs(c.frame.color - d.frame.color).max() < 1e-4
    assert first.render(eye, width=96, height=80).splats == b.splats   # kept for every later view


def test_a_hierarchy_built_after_a_facing_picture_holds_the_whole_surface():
    """A hierarchy serves every view: built after a picture that sampled only the faces its eye sees,
    it holds the whole surface's splats, as one built without that picture."""
    mesh = box()
    eye = CameraSpec(eye=EYE, target=(0.0, 0.0, 0.0))
    first = surfsplat.prepare(mesh)
    facing = first.render(eye, width=96, height=80).splats
    whole = surfsplat.prepare(mesh)
    camera = whole.camera(eye, 96, 80)
    expected = len(whole.sample(camera).points())
    assert facing < 0.7 * expected
    assert len(first.tree(first.camera(eye, 96, 80)).data.points) == expected


@pytest.mark.parametrize("technique, options", [("phong", None), ("ewa", RenderOptions(
    visibility=VisibilityOptions(cull_backfaces=False)))])
def test_pictures_that_keep_back_faces_sample_the_whole_surface(technique, options):
    view = surfsplat.prepare(box())
    result = view.render(CameraSpec(eye=EYE, target=(0.0, 0.0, 0.0)), technique=technique, options=options,
                         width=64, height=64)
    whole = surfsplat.prepare(box())
    assert result.splats == len(whole.sample(whole.camera(CameraSpec(eye=EYE, target=(0.0, 0.0, 0.0)), 64,
                                                          64)).points())
