"""The planning-scene data file: defaults (docs/hardware.md §2), validation, poses, and its effect
on the arm model's collision checks."""

import math

import coal
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene, SceneError, default_scene_path


def test_default_scene_holds_the_feeding_setup(scene):
    assert default_scene_path().is_file()
    for name in ("table", "plate", "bowl", "user_head", "user_torso", "ground"):
        assert name in scene.names
    assert any(n.startswith("wheelchair") for n in scene.names)
    head = scene.get("user_head")
    assert head.shape == "sphere" and head.radius == pytest.approx(0.10)
    np.testing.assert_allclose(head.xyz, [0.28, 0.40, 0.75])
    np.testing.assert_allclose(scene.get("plate").xyz[:2], [0.25, -0.30])


def test_default_scene_geometry_is_plausible(spec, scene):
    table = scene.get("table")
    top = table.xyz[2] + table.size[2] / 2
    assert -0.05 <= top <= 0.01  # table top ≈ level with the arm base
    # In front of the user (−y) and clear of the arm base footprint.
    assert table.xyz[1] + table.size[1] / 2 < -spec.collision.base_radius - 0.05
    assert scene.get("ground").xyz[2] < -0.5
    head = scene.get("user_head")
    for name in ("user_torso", "wheelchair_back"):
        body = scene.get(name)
        assert body.xyz[1] > head.xyz[1] - 0.01  # behind the face
        assert body.xyz[2] < head.xyz[2]  # below the head
    assert scene.get("plate").utensil_contact and not head.utensil_contact


def test_geometry_matches_the_declared_shapes(scene):
    table = scene.get("table").geometry()
    assert isinstance(table, coal.Box)
    np.testing.assert_allclose(table.halfSide, np.array(scene.get("table").size) / 2)
    assert isinstance(scene.get("user_head").geometry(), coal.Sphere)
    assert isinstance(scene.get("plate").geometry(), coal.Cylinder)
    assert isinstance(scene.get("ground").geometry(), coal.Halfspace)
    cap = Scene.from_dict({"objects": [
        {"name": "pole", "shape": "capsule", "radius": 0.02, "length": 0.3}]}).get("pole")
    g = cap.geometry()
    assert isinstance(g, coal.Capsule) and g.halfLength == pytest.approx(0.15)


def test_rpy_and_quaternion_poses_agree():
    rpy = (0.3, -0.7, 1.9)
    w, x, y, z = np.roll(Rotation.from_euler("xyz", rpy).as_quat(), 1)  # scipy is xyzw
    s = Scene.from_dict({"objects": [
        {"name": "a", "shape": "sphere", "radius": 0.1, "xyz": [1, 2, 3], "rpy": list(rpy)},
        {"name": "b", "shape": "sphere", "radius": 0.1, "xyz": [1, 2, 3], "wxyz": [w, x, y, z]},
    ]})
    A, B = s.get("a").pose, s.get("b").pose
    np.testing.assert_allclose(A, B, atol=1e-12)
    np.testing.assert_allclose(A[:3, :3], Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(A[:3, 3], [1, 2, 3])


def test_scene_round_trips_through_the_validated_model(scene):
    again = Scene.from_dict(scene.model_dump())
    assert again == scene


def _one(obj: dict) -> dict:
    return {"objects": [obj]}


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        (_one({"name": "lamp", "shape": "cone", "radius": 0.1}),
         ["object 'lamp'", "'cone'", "'box'", "'halfspace'"]),
        (_one({"name": "table", "shape": "box", "size": [1.0, -0.5, 0.1]}),
         ["object 'table'", "size.1", "greater than 0"]),
        (_one({"name": "head", "shape": "sphere", "radius": math.nan}),
         ["object 'head'", "radius", "finite"]),
        (_one({"name": "cup", "shape": "cylinder", "radius": 0.05}),
         ["object 'cup'", "length", "required"]),
        (_one({"name": "cup", "shape": "cylinder", "radius": 0.05, "length": 0.1,
               "xyz": [0, math.inf, 0]}), ["object 'cup'", "xyz.1", "finite"]),
        (_one({"name": "cup", "shape": "sphere", "radius": 0.05, "rpy": [0, 0, 0],
               "wxyz": [1, 0, 0, 0]}), ["object 'cup'", "either rpy or wxyz"]),
        (_one({"name": "cup", "shape": "sphere", "radius": 0.05, "wxyz": [1, 1, 0, 0]}),
         ["object 'cup'", "unit quaternion"]),
        (_one({"name": "cup", "shape": "sphere", "radius": 0.05, "colour": "red"}),
         ["object 'cup'", "colour", "Extra inputs"]),
        ({"objects": [{"name": "x", "shape": "sphere", "radius": 0.1},
                      {"name": "x", "shape": "sphere", "radius": 0.2}]},
         ["duplicate object name 'x'"]),
        ({"version": 2, "objects": []}, ["version"]),
    ],
)
def test_bad_scenes_name_the_object_and_field(data, expected):
    with pytest.raises(SceneError) as err:
        Scene.from_dict(data)
    for text in expected:
        assert text in str(err.value)


def test_the_scoop_heading_is_one_constant_of_the_arm_scene_the_scripts_use():
    # one source (arm/scene.py) for the sim scripts and the feeding tree
    from articutool.arm.scene import SCOOP_HEADING
    from articutool.sim import scenes

    assert scenes.SCOOP_HEADING is SCOOP_HEADING
    assert SCOOP_HEADING[2] == 0.0 and np.linalg.norm(SCOOP_HEADING) == pytest.approx(1.0)


def test_bad_files_are_reported(tmp_path):
    with pytest.raises(SceneError, match="cannot read scene"):
        Scene.load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[[objects]\nname = 'x'\n", encoding="utf-8")
    with pytest.raises(SceneError, match="not valid TOML"):
        Scene.load(bad)
    nan = tmp_path / "nan.toml"
    nan.write_text('[[objects]]\nname = "ball"\nshape = "sphere"\nradius = nan\n',
                   encoding="utf-8")
    with pytest.raises(SceneError, match=r"object 'ball' \(objects\[0\]\) field radius"):
        Scene.load(nan)


def test_a_scene_file_changes_what_the_arm_collides_with(spec, tmp_path):
    q = np.r_[spec.arm.configuration("AbovePlate"), 0.0, 0.0]
    assert not ArmModel(spec).in_collision(q)
    path = tmp_path / "raised_floor.toml"
    path.write_text(
        '[[objects]]\nname = "shelf"\nshape = "halfspace"\nxyz = [0.0, 0.0, 0.40]\n'
        '[[objects]]\nname = "ball"\nshape = "sphere"\nradius = 0.05\n'
        "xyz = [-0.5, 0.5, 0.3]\n",
        encoding="utf-8",
    )
    model = ArmModel(spec, scene=Scene.load(path))
    pairs = model.colliding_pairs(q)
    assert ("utensil_spoon", "scene/shelf") in pairs  # the tip hangs below z = 0.40
    assert not any(b == "scene/ball" for _, b in pairs)
    # A wall through x = −0.3: its free side (local +z) turned to face +x or −x by the rpy.
    def wall(pitch: float) -> ArmModel:
        path.write_text(
            '[[objects]]\nname = "wall"\nshape = "halfspace"\nxyz = [-0.3, 0.0, 0.0]\n'
            f"rpy = [0.0, {pitch!r}, 0.0]\n",
            encoding="utf-8",
        )
        return ArmModel(spec, scene=Scene.load(path))

    assert wall(math.pi / 2).colliding_pairs(q) == []  # the arm is on the free side
    assert ("j2n6s200_link_2", "scene/wall") in wall(-math.pi / 2).colliding_pairs(q)
