"""Issue 25, "resume from here": a session restored from a saved state and replayed with the
forces its ticks had continues bit for bit as the original did (MuJoCo's state per tick); a
spring pull; the measured contacts."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from dcmviz.config import Config
from dcmviz.session import Session


def walk(backend: str, seconds: float) -> Session:
    session = Session(Config().replace(sim={"backend": backend}), backend=backend)
    session.run(seconds)
    return session


@pytest.mark.parametrize("backend", ["lip", "mujoco"])
def test_restored_and_replayed_session_continues_bit_for_bit(backend: str) -> None:
    """Save the state after a push started, let the walk go on (the ticks' forces and physical
    states kept), go back: restore + replay reaches the kept state exactly, and the ticks after
    it equal those the original walk took (a gain changed in between does not leak back)."""
    session = walk(backend, 2.0)
    session.push((0.0, 70.0, 0.0), 0.4)
    session.step()
    saved = session.save_state()
    forces, physics = [], []
    for _ in range(60):
        session.step()
        tick = session.tick()
        forces.append({p.body: p.force for p in tick.pushes})
        physics.append(tick.physics)
    assert any(forces), "the push acts in the replayed ticks"
    original = []
    for _ in range(200):
        session.step()
        original.append((session.tick().physics, session.tick().command.v_cmd.copy()))
    session.set_config(session.config.replace(control={"k_xi": 5.0}))  # a change afterwards

    session.restore_state(saved)
    session.replay(forces)
    np.testing.assert_array_equal(session.tick().physics, physics[-1])  # exactly the frame
    assert session.config.control.k_xi == 3.0  # the walk's own gains at that tick
    for physics_then, v_cmd_then in original:
        session.step()
        np.testing.assert_array_equal(session.tick().physics, physics_then)
        np.testing.assert_array_equal(session.tick().command.v_cmd, v_cmd_then)


def test_a_state_restores_only_into_its_own_backend() -> None:
    a, b = walk("lip", 0.1), walk("lip", 0.1)
    with pytest.raises(ValueError, match="another backend"):
        b.restore_state(a.save_state())


@pytest.mark.parametrize("backend", ["lip", "mujoco"])
def test_a_pickled_state_continues_bit_for_bit_in_a_new_session(backend: str) -> None:
    """A state saved during a push, pickled and unpickled (as the sweep ships a trial's prefix
    to a worker), continues in a session built for it (:meth:`Session.from_state`) exactly as the
    original session does: MuJoCo's physical state and the commanded VRP equal every tick for
    1.5 s, and so do the metrics (largest DCM error, fall)."""
    import pickle

    session = walk(backend, 2.0)
    session.push((0.0, 70.0, 0.0), 0.4)
    session.step()
    state = pickle.loads(pickle.dumps(session.save_state()))
    resumed = Session.from_state(state)
    assert resumed.backend is not session.backend and resumed.robot is session.robot
    for _ in range(750):
        session.step()
        resumed.step()
        np.testing.assert_array_equal(resumed.tick().physics, session.tick().physics)
        np.testing.assert_array_equal(resumed.tick().command.v_cmd, session.tick().command.v_cmd)
    assert resumed.metrics.max_dcm_error_m == session.metrics.max_dcm_error_m > 0.0
    assert resumed.metrics.fell == session.metrics.fell


def test_a_robot_pickles_as_its_name() -> None:
    """Unpickled, a robot is this process's own (load_robot's, built once); a robot file's is
    named by its absolute path, so a worker elsewhere in the tree finds it."""
    import pickle
    from pathlib import Path

    from dcmviz.robots import load_robot

    talos = load_robot("talos")
    assert pickle.loads(pickle.dumps(talos)) is talos
    path = str(Path(__file__).resolve().parents[1] / "robots" / "talos_arms.toml")
    arms = pickle.loads(pickle.dumps(load_robot(path)))
    assert arms.name == path and arms.nu == talos.nu + 8


@pytest.mark.parametrize("backend", ["lip", "mujoco"])
def test_a_spring_pull_is_k_times_the_stretch_and_moves_the_body(backend: str) -> None:
    """The first tick of a pull pushes the body with k (target − grab point), the grab point
    where the body was grabbed (no velocity yet); the tick reports it as an external force on
    that body and the pull itself; the body moves towards the target; release ends it."""
    session = walk(backend, 1.5)
    body = "torso"
    start = session.tick().pushes  # none yet
    assert start == ()
    com = session.tick().state.com
    grab = com + np.array([0.0, 0.0, 0.1])
    target = grab + np.array([0.0, 0.15, 0.0])
    k = 15.0 * session.mass
    session.pull(body, target, k, 0.0, grab=grab)
    session.step()
    tick = session.tick()
    (push,) = tick.pushes
    assert push.body == body and tick.pull is not None
    np.testing.assert_allclose(push.force, k * (target - grab), rtol=1e-9)
    y0 = tick.state.com[1]
    for _ in range(int(0.3 / session.backend.control_dt)):
        session.step()
    assert session.tick().state.com[1] > y0 + 0.01  # pulled along +y
    session.release()
    session.step()
    assert session.tick().pushes == () and session.tick().pull is None


def test_mujoco_contacts_are_the_soles_measured_centres_of_pressure() -> None:
    """Each sole's centre of pressure from its contact wrench (cfrc_ext about the CoM) equals
    the force-weighted mean of MuJoCo's contact points on that sole (mj_contactForce, an
    independent computation), and the forces sum to the measured contact force."""
    session = walk("mujoco", 1.3)  # in double support then single support: both cases
    backend = session.backend
    model, data = backend.model, backend.data
    checked = 0
    for _ in range(300):
        session.step()
        # the contact forces of the last physics substep, from the constraint solver
        per_sole: dict[int, list] = {}
        for i in range(data.ncon):
            c = data.contact[i]
            f = np.zeros(6)
            mujoco.mj_contactForce(model, data, i, f)
            frame = c.frame.reshape(3, 3)
            world = frame.T @ f[:3]
            bodies = {int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])}
            for k, sole in enumerate(backend._sole_bodies):
                if int(sole) in bodies:
                    sign = 1.0 if int(model.geom_bodyid[c.geom2]) == int(sole) else -1.0
                    per_sole.setdefault(k, []).append((c.pos.copy(), sign * world))
        contacts = session.tick().contacts
        if len(contacts) != len(per_sole) or not contacts:
            continue
        for (cop, force), k in zip(contacts, sorted(per_sole), strict=True):
            points = np.array([p for p, _ in per_sole[k]])
            forces = np.array([f for _, f in per_sole[k]])
            fz = forces[:, 2]
            expected = (fz @ points) / fz.sum()
            np.testing.assert_allclose(force, forces.sum(axis=0), rtol=0.02, atol=2.0)
            np.testing.assert_allclose(cop[:2], expected[:2], atol=0.004)
        checked += 1
    assert checked > 100
