"""The Jaco 2 + Articutool model: FK against Kinova's DH table, wrist frames against Eq. 4.1,
vectorised F0 kinematics against Pinocchio, Jacobians against finite differences, collision."""

import itertools

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene
from articutool.tool import kinematics as kin
from conftest import packaged_spec

SPEC = packaged_spec()
TWO_PI = 2 * np.pi


@pytest.fixture(scope="module")
def m8() -> ArmModel:
    return ArmModel(SPEC, utensil="spoon", dof=8)


@pytest.fixture(scope="module")
def m6() -> ArmModel:
    return ArmModel(SPEC, utensil="spoon", dof=6)


def angles(n: int, lo: float = -TWO_PI, hi: float = TWO_PI):
    return arrays(np.float64, n, elements=st.floats(lo, hi, allow_nan=False))


wrist_angles = arrays(np.float64, 2, elements=st.floats(-np.pi, np.pi))


# --------------------------------------------------- independent Kinova DH model --
# Kinova's classic DH table for the Jaco 2 6-DOF non-spherical wrist (docs/hardware.md §1),
# standard DH: A_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i). Lengths from Kinova, not the spec.
D1, D2, D3, D4, D5, D6, E2 = 0.2755, 0.41, 0.2073, 0.0741, 0.0741, 0.160, 0.0098
AA = np.radians(60.0) / 2  # half the 60° wrist bend
SA = np.sin(AA) / np.sin(2 * AA)
DH_ALPHA = [np.pi / 2, np.pi, np.pi / 2, 2 * AA, 2 * AA, np.pi]
DH_A = [0.0, D2, 0.0, 0.0, 0.0, 0.0]
DH_D = [D1, 0.0, -E2, -(D3 + SA * D4), -SA * (D4 + D5), -(SA * D5 + D6)]
# DH angle = sign * physical angle + offset. Kinova's physical angles are the URDF angles.
DH_SIGN = np.array([-1.0, 1, 1, 1, 1, 1])
DH_OFFSET = np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, -np.pi, np.pi / 2])


def dh_fk(q: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    for th, d, a, al in zip(DH_SIGN * q + DH_OFFSET, DH_D, DH_A, DH_ALPHA, strict=True):
        ct, st_, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
        T = T @ np.array([
            [ct, -st_ * ca, st_ * sa, a * ct],
            [st_, ct * ca, -ct * sa, a * st_],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ])
    return T


@settings(max_examples=300, deadline=None)
@given(q=angles(6))
def test_ee_fk_matches_kinova_dh_table(m8, m6, q):
    """Position within 0.1 mm; the DH frames 0 and 6 coincide with link_base and end_effector
    (with these angle offsets the frame-convention difference is the identity rotation)."""
    T_dh = dh_fk(q)
    for model in (m8, m6):
        T = model.ee_pose(q)
        assert np.linalg.norm(T[:3, 3] - T_dh[:3, 3]) < 1e-4
        np.testing.assert_allclose(T[:3, :3], T_dh[:3, :3], atol=1e-9)


def test_ee_pose_accepts_full_configuration_and_ignores_the_wrist(m8):
    q = SPEC.arm.configuration("Home")
    T = m8.ee_pose(q)
    np.testing.assert_allclose(m8.ee_pose(np.r_[q, 0.7, -1.2]), T, atol=1e-12)
    assert T.shape == (4, 4)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1])


def test_above_plate_points_down_over_the_plate(m8):
    T = m8.ee_pose(SPEC.arm.configuration("AbovePlate"))
    np.testing.assert_allclose(T[:3, 3], [0.25, -0.24, 0.49], atol=0.01)
    assert T[2, 2] < -0.9  # approach axis within ~25° of straight down


# ----------------------------------------------------------------- wrist frames --
def _urdf_pose(xyz, rpy) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x-y-z = URDF rpy
    T[:3, 3] = xyz
    return T


@settings(max_examples=100, deadline=None)
@given(q_arm=angles(6), q_wrist=wrist_angles)
def test_tool_base_is_the_end_effector_times_the_mount(m8, q_arm, q_wrist):
    q = np.r_[q_arm, q_wrist]
    w = SPEC.wrist
    expected = m8.ee_pose(q) @ _urdf_pose(w.mount_xyz, w.mount_rpy)
    np.testing.assert_allclose(m8.tool_base_pose(q), expected, atol=1e-12)
    np.testing.assert_allclose(m8.tool_base_pose(q_arm), expected, atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(q_arm=angles(6), q_wrist=wrist_angles, utensil=st.sampled_from(sorted(SPEC.utensils)))
def test_tip_frame_in_F0_is_the_wrist_model(q_arm, q_wrist, utensil):
    model = _model(utensil)
    q = np.r_[q_arm, q_wrist]
    F0, tip = model.tool_base_pose(q), model.tip_pose(q)
    rel = np.linalg.inv(F0) @ tip
    np.testing.assert_allclose(rel[:3, :3], kin.rotation(q_wrist), atol=1e-12)
    np.testing.assert_allclose(rel[:3, 1], kin.up_vector(q_wrist), atol=1e-12)
    # Position: pitch axis at pitch_z, then roll_dz, utensil mount and tip offset.
    w, u = SPEC.wrist, SPEC.utensil(utensil)
    Ry = Rotation.from_rotvec([0.0, -q_wrist[0], 0.0]).as_matrix()
    Rz = Rotation.from_rotvec([0.0, 0.0, q_wrist[1]]).as_matrix()
    local = np.array([u.tip_x, 0.0, w.utensil_mount_dz + u.tip_z])
    p = np.array([0, 0, w.pitch_z]) + Ry @ (np.array([0, 0, w.roll_dz]) + Rz @ local)
    np.testing.assert_allclose(rel[:3, 3], p, atol=1e-12)


_MODELS: dict[str, ArmModel] = {}


def _model(utensil: str) -> ArmModel:
    if utensil not in _MODELS:
        _MODELS[utensil] = ArmModel(SPEC, utensil=utensil)
    return _MODELS[utensil]


def test_six_dof_model_is_the_eight_dof_model_with_the_wrist_at_zero(m8, m6):
    assert (m8.nq, m6.nq) == (8, 6)
    assert m8.joint_names == [*SPEC.arm.joint_names, *SPEC.wrist.joint_names]
    assert m6.joint_names == SPEC.arm.joint_names
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = rng.uniform(-TWO_PI, TWO_PI, 6)
        for frame in ("ee", "tool_base", "tip"):
            np.testing.assert_allclose(
                m6.frame_pose(q, frame), m8.frame_pose(np.r_[q, 0, 0], frame), atol=1e-12
            )
        np.testing.assert_allclose(
            m6.frame_jacobian(q, "tip"), m8.frame_jacobian(np.r_[q, 0, 0], "tip")[:, :6],
            atol=1e-12,
        )


def test_limits_come_from_the_spec(m8, m6):
    w = SPEC.wrist
    np.testing.assert_array_equal(m8.lower, [*SPEC.arm.lower, w.pitch_limits[0], w.roll_limits[0]])
    np.testing.assert_array_equal(m8.upper, [*SPEC.arm.upper, w.pitch_limits[1], w.roll_limits[1]])
    np.testing.assert_array_equal(m8.velocity_limits, [*SPEC.arm.max_velocity, *w.max_velocity])
    np.testing.assert_array_equal(m6.lower, SPEC.arm.lower)
    np.testing.assert_array_equal(m6.velocity_limits, SPEC.arm.max_velocity)
    np.testing.assert_array_equal(m8.model.lowerPositionLimit, m8.lower)
    np.testing.assert_array_equal(m8.model.upperPositionLimit, m8.upper)
    np.testing.assert_array_equal(m8.model.velocityLimit, m8.velocity_limits)


# ------------------------------------------------------ vectorised F0 kinematics --
def test_vectorised_tool_base_matches_pinocchio(m8):
    rng = np.random.default_rng(7)
    q = rng.uniform(-TWO_PI, TWO_PI, (64, 6))
    qd = rng.uniform(-1.0, 1.0, (64, 6))
    R = m8.tool_base_rotations(q)
    R2, w2 = m8.tool_base_kinematics(q, qd)
    w = m8.tool_base_angular_velocity(q, qd)
    assert R.shape == (64, 3, 3) and w.shape == (64, 3)
    np.testing.assert_array_equal(R, R2)
    np.testing.assert_array_equal(w, w2)
    fid = m8.model.getFrameId("atool_base")
    data = m8.model.createData()
    for k in range(len(q)):
        qk = np.r_[q[k], 0.3, -0.4]  # the wrist must not matter
        pin.framesForwardKinematics(m8.model, data, qk)
        np.testing.assert_allclose(R[k], data.oMf[fid].rotation, atol=1e-12)
        pin.computeJointJacobians(m8.model, data, qk)
        J = pin.getFrameJacobian(m8.model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(w[k], J[3:, :6] @ qd[k], atol=1e-12)


def test_vectorised_tool_base_accepts_any_leading_shape(m8):
    rng = np.random.default_rng(8)
    q, qd = rng.uniform(-3, 3, (2, 3, 6)), rng.uniform(-1, 1, (2, 3, 6))
    R, w = m8.tool_base_kinematics(q, qd)
    assert R.shape == (2, 3, 3, 3) and w.shape == (2, 3, 3)
    np.testing.assert_allclose(R[1, 2], m8.tool_base_rotations(q[1, 2]), atol=1e-15)
    np.testing.assert_allclose(w[1, 2], m8.tool_base_angular_velocity(q[1, 2], qd[1, 2]))
    assert m8.tool_base_rotations(np.zeros((0, 6))).shape == (0, 3, 3)


# ------------------------------------------------------------------- Jacobians --
def _fd_jacobian(model: ArmModel, q: np.ndarray, frame: str, h: float = 1e-6) -> np.ndarray:
    J = np.zeros((6, model.nq))
    for i in range(model.nq):
        dq = np.zeros(model.nq)
        dq[i] = h
        Tp, Tm = model.frame_pose(q + dq, frame), model.frame_pose(q - dq, frame)
        J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        # World-frame angular velocity: Ṙ Rᵀ ≈ log(R(q+h) R(q−h)ᵀ) / 2h.
        J[3:, i] = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
    return J


@settings(max_examples=60, deadline=None)
@given(q_arm=angles(6), q_wrist=angles(2, -np.pi / 2, np.pi / 2),
       frame=st.sampled_from(["tip", "tool_base", "ee", "utensil"]),
       dof=st.sampled_from([6, 8]))
def test_frame_jacobians_match_finite_differences(m8, m6, q_arm, q_wrist, frame, dof):
    model = m8 if dof == 8 else m6
    q = np.r_[q_arm, q_wrist] if dof == 8 else q_arm
    J = model.frame_jacobian(q, frame)
    assert J.shape == (6, model.nq)
    np.testing.assert_allclose(J, _fd_jacobian(model, q, frame), atol=1e-6)


# --------------------------------------------------------------- input checking --
def test_unknown_utensil_and_dof_name_the_allowed_values():
    with pytest.raises(ValueError, match=r"unknown utensil 'knife'.*fork.*soup_spoon.*spoon"):
        ArmModel(SPEC, utensil="knife")
    with pytest.raises(ValueError, match=r"dof must be one of \(6, 8\); got 7"):
        ArmModel(SPEC, dof=7)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda m: m.ee_pose(np.zeros(7)), r"q_arm must have shape \(6 or 8,\)"),
        (lambda m: m.tip_pose(np.zeros(6)), r"q must have shape \(8,\)"),
        (lambda m: m.tip_pose(np.full(8, np.nan)), "finite"),
        (lambda m: m.frame_jacobian(np.zeros(8), "elbow"), "unknown frame 'elbow'"),
        (lambda m: m.in_collision(np.zeros((2, 8))), r"shape \(8,\)"),
        (lambda m: m.collisions(np.zeros(8)), r"shape \(N, 8\)"),
        (lambda m: m.first_collision(np.full((3, 8), np.nan)), "finite"),
        (lambda m: m.tool_base_rotations(np.zeros((4, 8))), r"shape \(\.\.\., 6\)"),
        (lambda m: m.tool_base_rotations([np.inf] * 6), "finite"),
        (lambda m: m.tool_base_angular_velocity(np.zeros((4, 6)), np.zeros((3, 6))),
         "qd_arm must have the shape"),
    ],
)
def test_bad_configurations_are_rejected(m8, call, match):
    with pytest.raises(ValueError, match=match):
        call(m8)


# -------------------------------------------------------------------- collision --
def _ik(model: ArmModel, target, frame: str, q0: np.ndarray) -> np.ndarray:
    """Damped least-squares position IK (uses the model's own Jacobian)."""
    q = q0.copy()
    for _ in range(500):
        e = np.asarray(target) - model.frame_pose(q, frame)[:3, 3]
        if np.linalg.norm(e) < 1e-6:
            break
        J = model.frame_jacobian(q, frame)[:3]
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(3), e)
    assert np.linalg.norm(e) < 1e-4, "test IK did not converge"
    return q


def _named(name: str, nq: int) -> np.ndarray:
    return np.r_[SPEC.arm.configuration(name), np.zeros(nq - 6)]


@pytest.mark.parametrize("utensil", sorted(SPEC.utensils))
@pytest.mark.parametrize("dof", [6, 8])
@pytest.mark.parametrize("name", ["Home", "AbovePlate", "Resting"])
def test_named_configurations_are_collision_free(name, dof, utensil):
    model = _model(utensil) if dof == 8 else ArmModel(SPEC, utensil=utensil, dof=6)
    q = _named(name, model.nq)
    assert model.colliding_pairs(q) == []
    assert not model.in_collision(q)
    assert model.min_distance(q) > 0.0


def test_tool_in_the_users_head_collides(m8):
    head = Scene.load().get("user_head")
    q = _ik(m8, head.xyz, "tip", _named("Home", 8))
    pairs = m8.colliding_pairs(q)
    assert ("utensil_spoon", "scene/user_head") in pairs
    assert m8.in_collision(q)
    assert m8.min_distance(q) < 0.0


def test_tool_pushed_into_the_table_collides(m8):
    q = _ik(m8, [0.30, -0.50, -0.03], "tip", _named("Home", 8))
    assert any(b == "scene/table" for _, b in m8.colliding_pairs(q))
    assert m8.in_collision(q)


def test_hand_folded_into_the_base_is_a_self_collision(m8):
    q = _ik(m8, [0.0, 0.0, 0.12], "ee", _named("Home", 8))
    pairs = m8.colliding_pairs(q)
    assert any("j2n6s200_link_base" in p and "j2n6s200_link_6" in p for p in pairs)


def test_the_utensil_may_touch_the_plate_but_the_arm_may_not():
    default = Scene.load()
    strict = Scene.from_dict(
        {"objects": [o.model_dump() | ({"utensil_contact": False} if o.name == "plate" else {})
                     for o in default.objects]}
    )
    loose, tight = ArmModel(SPEC, scene=default), ArmModel(SPEC, scene=strict)
    plate = default.get("plate")
    q = _ik(loose, [plate.xyz[0], plate.xyz[1], plate.xyz[2] + 0.005], "tip",
            _named("AbovePlate", 8))
    assert ("utensil_spoon", "scene/plate") not in loose.colliding_pairs(q)
    assert ("utensil_spoon", "scene/plate") in tight.colliding_pairs(q)
    assert ("atool_distal", "scene/plate") in loose.collision_pairs


def test_collision_pairs_skip_adjacent_bodies_and_static_ones(m8):
    pairs = {frozenset(p) for p in m8.collision_pairs}
    chain = ["j2n6s200_link_base"] + [f"j2n6s200_link_{i}" for i in range(1, 7)]
    for a, b in itertools.pairwise(chain):
        assert frozenset((a, b)) not in pairs
    for a, b in SPEC.collision.excluded_pairs:
        assert frozenset((a, b)) not in pairs
    for bolted in ("j2n6s200_link_5", "j2n6s200_link_6"):
        assert frozenset(("atool_body", bolted)) not in pairs
    assert frozenset(("j2n6s200_link_2", "j2n6s200_link_6")) in pairs
    assert frozenset(("j2n6s200_link_3", "utensil_spoon")) in pairs
    assert not any("j2n6s200_link_base" in p and any(n.startswith("scene/") for n in p)
                   for p in pairs)
    assert not any(all(n.startswith("scene/") for n in p) for p in pairs)
    # Every robot body except the base is checked against every obstacle.
    for o in Scene.load().names:
        assert frozenset(("j2n6s200_link_3", f"scene/{o}")) in pairs


def test_empty_scene_checks_only_self_collision():
    model = ArmModel(SPEC, scene=Scene())
    assert not any(n.startswith("scene/") for p in model.collision_pairs for n in p)
    q = _ik(model, Scene.load().get("user_head").xyz, "tip", _named("Home", 8))
    assert "scene/user_head" not in {n for p in model.colliding_pairs(q) for n in p}


def test_excluded_pair_with_unknown_body_is_rejected():
    data = SPEC.model_dump()
    data["collision"]["excluded_pairs"] = [("j2n6s200_link_3", "elbow_pad")]
    bad = type(SPEC).model_validate(data)
    with pytest.raises(ValueError, match="excluded_pairs: unknown body 'elbow_pad'"):
        ArmModel(bad)


def test_collision_agrees_with_signed_distances_pair_by_pair(m8):
    """Guards the coal GJK-only false negatives (see ArmModel.__init__): the boolean query
    and the signed distances must name the same pairs on random configurations."""
    rng = np.random.default_rng(11)
    lo = np.r_[np.maximum(m8.lower[:6], -1.5 * np.pi), m8.lower[6:]]
    hi = np.r_[np.minimum(m8.upper[:6], 1.5 * np.pi), m8.upper[6:]]
    n_colliding = 0
    for q in rng.uniform(lo, hi, (300, 8)):
        d = m8.pair_distances(q)
        by_distance = [p for p, di in zip(m8.collision_pairs, d, strict=True) if di < 0]
        assert m8.colliding_pairs(q) == by_distance
        assert m8.in_collision(q) == bool(by_distance)
        assert m8.min_distance(q) == pytest.approx(d.min(), abs=1e-6)
        n_colliding += bool(by_distance)
    assert 0 < n_colliding < 300  # both outcomes were exercised


@pytest.mark.parametrize(("dof", "utensil"), [(6, "spoon"), (8, "spoon"), (8, "fork")])
def test_broad_phase_check_gives_the_pair_loops_answer(dof, utensil):
    """``in_collision`` (coal's dynamic AABB tree broad phase, which the planners use) says
    what checking every pair says (``colliding_pairs``), on random configurations and on
    pairs straddling a contact (bisected to 1e-7 rad), where a broad phase could cut
    wrongly."""
    m = ArmModel(SPEC, utensil=utensil, dof=dof)
    rng = np.random.default_rng(5)
    lo, hi = np.maximum(m.lower, -1.5 * np.pi), np.minimum(m.upper, 1.5 * np.pi)
    qs = list(rng.uniform(lo, hi, (400, m.nq)))
    free = [q for q in qs if not m.colliding_pairs(q)]
    hit = [q for q in qs if m.colliding_pairs(q)]
    assert free and hit  # both outcomes exercised
    for a, b in zip(free[:30], hit[:30], strict=False):
        s0, s1 = 0.0, 1.0  # bisect the segment a -> b to its first contact
        while s1 - s0 > 1e-7:
            s = 0.5 * (s0 + s1)
            s0, s1 = (s0, s) if m.colliding_pairs(a + s * (b - a)) else (s, s1)
        qs += [a + s0 * (b - a), a + s1 * (b - a)]
    for q in qs:
        assert m.in_collision(q) == bool(m.colliding_pairs(q))
    # The batch query (the broad phase on its own copies, one call) answers the same.
    flags = [m.in_collision(q) for q in qs]
    assert m.collisions(np.array(qs)).tolist() == flags
    assert m.first_collision(np.array(qs)) == flags.index(True)
    assert m.first_collision(np.array(free)) is None
