"""MuJoCo engine: the rigid four-bar as a reference for the flexible engines.

Model (MJCF generated from the scenario's :class:`tmm_core.FourBarMechanism`): three bodies on
hinges about z -- crank at A, coupler on the crank at B, rocker at D -- and the loop closed at C
by an equality ``connect`` between a site at the coupler's end and one at the rocker's end
(solref = solref_factor * dt, dampratio 1; MuJoCo's refsafe raises a time constant below 2 dt to
2 dt; solimp = (s, s, 0.001, 0.5, 2)). Each body's frame sits at its link's start joint with
local x along the link (crank A->B, coupler B->C, rocker D->C), turned by the ground angle so
the crank hinge angle *is* the crank angle from the ground line. Mass, centre of mass and z
inertia of every link are the exact rigid-body values of the link data (:func:`link_inertia`).
Sites sit at every mesh node of every link. Contacts are off (there are no geoms).

Drive:

* prescribed -- a stiff PD servo (``general`` actuator, affine bias) with natural frequency
  ``servo_frequency_Hz`` (default ``1 / (20 dt)``, i.e. omega_n dt = pi/10), critically damped
  at the armature plus the mean linkage inertia. The armature is ``ARMATURE_RATIO`` times the
  linkage's largest reflected inertia at the crank, so the servo sees a nearly constant inertia;
  the reference acceleration is fed forward through it. Drive torque = servo force - armature
  * crank angular acceleration (the torque the linkage itself takes).
* torque -- a ``motor`` actuator; the servo and the armature are switched off.

Integrator: semi-implicit Euler. MuJoCo evaluates forces at the start of a step, so the control
of step k is the drive at t_k (sampling it elsewhere gives a spurious torque offset). Steps run
through :func:`mujoco.rollout.rollout`. Every output of a sample is a MuJoCo sensor evaluated in
the forward pass at that sample's state, which precedes the step from it; so one extra step is
rolled out per macro step to get the sensors at t_next, and its end state is discarded.

Outputs, one sample per internal step: crank angle and speed (hinge sensors), drive torque,
node positions (node sites), extras ``coupler_angle_rad`` / ``rocker_angle_rad`` (global angle
of the link's local x axis, CCW from global X, not wrapped, as :attr:`tmm_core.LinkMotion.angle`)
and ``loop_closure_m`` (distance between the two connect sites: the soft constraint's own
error), and the rigid ("quasi-static") gauge strains: D'Alembert loads from MuJoCo's own node
accelerations on the instantaneous structure, solved linearly by :func:`tmm_core.solve_static`.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np
from mujoco import rollout

from tmm_core import InputError, LoadCase, SliderCrankMechanism, gauge_strains, solve_static

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in

SLIDER_BODY_KG = 1e-6     # the slide joint's block body; the block's mass sits on the coupler's end
ARMATURE_RATIO = 10.0      # armature / largest reflected linkage inertia at the crank
SERVO_STEPS = 20.0         # default servo period in internal steps: f_servo = 1 / (20 dt)
SERVO_GROUP, MOTOR_GROUP = 1, 2


def link_inertia(link):
    """Exact rigid-body (mass, centre of mass x, z inertia about it) of a link (see
    :meth:`tmm_core.Link.rigid_body`)."""
    try:
        return link.rigid_body()
    except InputError as exc:
        raise EngineError(f"mujoco: {exc}; a rigid body needs a positive mass") from None


def reflected_inertia(mech, n: int = 72) -> np.ndarray:
    """Linkage inertia seen at the crank [kg m^2] at ``n`` crank positions over a revolution
    (used only to size the servo)."""
    return mech.crank_inertia(np.linspace(0.0, 2 * math.pi, n, endpoint=False))[0]


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _f(*v):
    return " ".join(f"{x:.17g}" for x in v)


class MujocoEngine:
    name = "mujoco"
    kinematic = False

    def __init__(self):
        self._dt = None

    @property
    def internal_step_s(self) -> float:
        if self._dt is None:
            raise EngineError("mujoco: reset() the engine before asking for its step")
        return self._dt

    # -- model --------------------------------------------------------------------------------
    def _mjcf(self, scenario: Scenario) -> str:
        mech, s, dt = scenario.mechanism, scenario.mujoco, self._dt
        g = scenario.gravity or (0.0, 0.0)
        gam = mech.ground_angle
        A = np.asarray(mech.pivot, dtype=float)

        def body(link, pos, euler_z, joint_extra="", inner=""):
            m, xc, Jc = link_inertia(link)
            sites = "".join(f'<site name="{link.name}_n{i}" pos="{_f(x, 0, 0)}"/>' for i, x in enumerate(link.stations))
            # Planar: only the z inertia acts; x/y values only have to pass the triangle inequality.
            return (f'<body name="{link.name}" pos="{_f(*pos, 0)}" euler="{_f(0, 0, euler_z)}">'
                    f'<joint name="{link.name}" type="hinge" axis="0 0 1"{joint_extra}/>'
                    f'<inertial pos="{_f(xc, 0, 0)}" mass="{m:.17g}" diaginertia="{_f(1e-6 * Jc, Jc, Jc)}"/>'
                    f'{sites}{inner}</body>')

        links = mech.links()
        crank, coupler = links[0], links[1]
        tree = body(crank, A, gam, f' armature="{self.armature:.17g}"',
                    body(coupler, (crank.length_m, 0.0), 0.0))
        last = {l.name: f"{l.name}_n{l.n_nodes - 1}" for l in links}
        if self.slider:
            # A light block on a slide joint along the guide, at the foot of the offset line; the
            # block's own mass is the coupler's end point mass (mech.links()).
            foot = A + mech.offset_m * np.array([-math.sin(gam), math.cos(gam)])
            tree += (f'<body name="slider" pos="{_f(*foot, 0)}" euler="{_f(0, 0, gam)}">'
                     f'<joint name="slider" type="slide" axis="1 0 0"/>'
                     f'<inertial pos="0 0 0" mass="{SLIDER_BODY_KG:.17g}" diaginertia="1e-9 1e-9 1e-9"/>'
                     f'<site name="slider_pin" pos="0 0 0"/></body>')
            closure = (last["coupler"], "slider_pin")
        else:
            D = A + mech.ground_m * np.array([math.cos(gam), math.sin(gam)])
            tree += body(links[2], D, gam)
            closure = (last["coupler"], last["rocker"])
        kp, kd = self.gains
        sensors = []
        for link in mech.links():
            sensors.append(f'<jointpos name="q_{link.name}" joint="{link.name}"/>')
            sensors.append(f'<frameangacc name="alpha_{link.name}" objtype="xbody" objname="{link.name}"/>')
            for i in range(link.n_nodes):
                site = f"{link.name}_n{i}"
                sensors.append(f'<framepos name="p_{site}" objtype="site" objname="{site}"/>')
                sensors.append(f'<framelinacc name="a_{site}" objtype="site" objname="{site}"/>')
        sensors += ['<jointvel name="w_crank" joint="crank"/>', '<actuatorfrc name="f_servo" actuator="servo"/>',
                    '<actuatorfrc name="f_motor" actuator="motor"/>']
        if self.slider:
            sensors += ['<jointpos name="q_slider" joint="slider"/>',
                        '<framepos name="p_slider_pin" objtype="site" objname="slider_pin"/>']
        return f"""<mujoco model="{'slidercrank' if self.slider else 'fourbar'}">
  <compiler angle="radian"/>
  <option timestep="{dt:.17g}" integrator="Euler" gravity="{_f(g[0], g[1], 0)}">
    <flag contact="disable"/>
  </option>
  <worldbody>{tree}</worldbody>
  <equality>
    <connect site1="{closure[0]}" site2="{closure[1]}" solref="{_f(s.solref_factor * dt, 1)}"
             solimp="{_f(s.solimp, s.solimp, 0.001, 0.5, 2)}"/>
  </equality>
  <actuator>
    <general name="servo" joint="crank" group="{SERVO_GROUP}" gainprm="{kp:.17g}" biastype="affine"
             biasprm="{_f(0, -kp, -kd)}"/>
    <motor name="motor" joint="crank" group="{MOTOR_GROUP}"/>
  </actuator>
  <sensor>{''.join(sensors)}</sensor>
</mujoco>"""

    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float, drive_inertia_kg_m2: float = 0.0) -> None:
        """Build the model and put the linkage at crank ``angle`` [rad] turning at ``speed`` [rad/s]
        (coupler and rocker from the closed-form kinematics), at time ``t0`` [s].
        ``drive_inertia_kg_m2``: a motor's rotor and flywheel inertia at the crank, carried as the
        crank's armature when driven by a torque."""
        if not (np.isfinite(drive_inertia_kg_m2) and drive_inertia_kg_m2 >= 0):
            raise EngineError(f"mujoco: drive inertia must not be negative, got {drive_inertia_kg_m2!r} kg m^2")
        self.drive_inertia = float(drive_inertia_kg_m2)
        s = scenario.mujoco
        mech = self.mech = scenario.mechanism
        self.slider = isinstance(mech, SliderCrankMechanism)
        self.link_names = tuple(l.name for l in mech.links())
        self.scenario, self._dt, self.t0, self.k = scenario, s.step_s, t0, 0
        J = reflected_inertia(mech)
        self.armature = ARMATURE_RATIO * float(J.max())
        wn = 2 * math.pi * (s.servo_frequency_Hz or 1.0 / (SERVO_STEPS * self._dt))
        inertia = self.armature + float(J.mean())
        self.gains = (inertia * wn**2, 2.0 * inertia * wn)
        self.xml = self._mjcf(scenario)
        try:
            self.model = mujoco.MjModel.from_xml_string(self.xml)
        except ValueError as exc:
            raise EngineError(f"mujoco: the generated model does not compile: {exc}") from None
        self.data = mujoco.MjData(self.model)
        self.structure = mech.structure()
        self.slices = {self.model.sensor(i).name: slice(self.model.sensor_adr[i],
                                                        self.model.sensor_adr[i] + self.model.sensor_dim[i])
                       for i in range(self.model.nsensor)}
        self.node_masses = {link.name: link.node_masses() for link in mech.links()}

        mo = mech.motion(angle, speed)
        gam = mech.ground_angle
        d = self.data
        if self.slider:
            third, third_rate = float(mo.slider_position), float(mo.slider_velocity)
        else:
            third, third_rate = _wrap(float(mo.rocker.angle) - gam), float(mo.rocker.omega)
        d.qpos[:] = [angle, _wrap(float(mo.coupler.angle - mo.crank.angle)), third]
        d.qvel[:] = [speed, float(mo.coupler.omega - mo.crank.omega), third_rate]
        d.time = t0
        self._set_drive(prescribed=True)
        self.state = np.empty(mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
        mujoco.mj_getState(self.model, d, self.state, mujoco.mjtState.mjSTATE_FULLPHYSICS)

    def _set_drive(self, prescribed: bool) -> None:
        """Prescribed: servo on with its armature; torque: motor only, the drive's inertia as armature."""
        self.model.opt.disableactuator = 1 << (MOTOR_GROUP if prescribed else SERVO_GROUP)
        self.model.dof_armature[0] = self.armature if prescribed else self.drive_inertia

    def node_stations(self) -> dict:
        """Local x [m] of the nodes (sites) this engine reports, per link."""
        return {link.name: link.stations for link in self.mech.links()}

    def initial_output(self) -> EngineOutput:
        q, w = self.data.qpos[0], self.data.qvel[0]
        return EngineOutput(np.array([self.t0]), np.array([q]), np.array([w]), np.array([np.nan]))

    def save(self):
        return self.k, self.state.copy()

    def restore(self, token) -> None:
        self.k, state = token
        self.state = state.copy()

    # -- stepping -----------------------------------------------------------------------------
    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput:
        t_start = self.t0 + self.k * self._dt
        n = steps_in(t_start, t_next, self._dt, "mujoco")
        ks = self.k + np.arange(n + 1)
        t = self.t0 + ks * self._dt           # step starts t_k .. t_next: integer step count
        ctrl = np.zeros((n + 1, 2))
        if drive.prescribed is not None:
            self._set_drive(prescribed=True)
            q, w, a = (np.broadcast_to(np.asarray(x, dtype=float), t.shape) for x in drive.prescribed(t))
            kp, kd = self.gains
            # kp u - kp q - kd qd = kp (q_ref - q) + kd (w_ref - qd) + armature a_ref
            ctrl[:, 0] = q + (kd * w + self.armature * a) / kp
        else:
            self._set_drive(prescribed=False)
            ctrl[:, 1] = drive.torque_at(t)
        bad = mujoco.mjtWarning.mjWARN_BADQACC
        before = self.data.warning[bad].number
        # One step more than the macro step: its forward pass gives the sensors at t_next.
        states, sens = rollout.rollout(self.model, self.data, self.state, ctrl[None])
        states, sens = states[0], sens[0, 1:]
        if self.data.warning[bad].number != before or not (np.all(np.isfinite(states)) and np.all(np.isfinite(sens))):
            raise EngineError(f"mujoco: the simulation diverged before t = {t_next:.6g} s (reduce solver.mujoco.step "
                              "or the servo frequency)")
        self.state = states[n - 1].copy()
        self.k += n
        return self._outputs(t[1:], sens)

    def _outputs(self, t, sens) -> EngineOutput:
        S = lambda name: sens[:, self.slices[name]]          # noqa: E731
        mech, gam = self.mech, self.mech.ground_angle
        q = {l: S(f"q_{l}")[:, 0] for l in self.link_names}
        alpha = {l: S(f"alpha_{l}")[:, 2] for l in self.link_names}   # absolute angular accelerations about z
        torque = S("f_servo")[:, 0] + S("f_motor")[:, 0] - self.model.dof_armature[0] * alpha["crank"]
        nodes, acc = {}, {}
        for link in mech.links():
            idx = range(link.n_nodes)
            nodes[link.name] = np.stack([S(f"p_{link.name}_n{i}")[:, :2] for i in idx], 1)
            acc[link.name] = np.stack([S(f"a_{link.name}_n{i}")[:, :2] for i in idx], 1)
        c_coupler = nodes["coupler"][:, -1]
        extras = {"coupler_angle_rad": ("rad", gam + q["crank"] + q["coupler"])}
        if self.slider:
            extras["slider_position_m"] = ("m", S("q_slider")[:, 0])
            c_other = S("p_slider_pin")[:, :2]
        else:
            extras["rocker_angle_rad"] = ("rad", gam + q["rocker"])
            c_other = nodes["rocker"][:, -1]
        extras["loop_closure_m"] = ("m", np.linalg.norm(c_coupler - c_other, axis=-1))
        self._closure_point = c_other
        gauges = self._rigid_strains(nodes, acc, alpha)
        return EngineOutput(t, q["crank"], S("w_crank")[:, 0], torque, gauges, nodes, extras)

    def _rigid_strains(self, nodes, acc, alpha) -> dict:
        """Quasi-static gauge strains of the rigid motion, all samples in one linear solve.

        MuJoCo's ``framelinacc`` is a proper acceleration (a - g, as an accelerometer reads), so
        the D'Alembert-plus-gravity node force m (g - a) is -m times the sensor reading; the
        node moment is -J alpha."""
        if not self.scenario.gauges:
            return {}
        mech = self.mech
        loads = {}
        for link in mech.links():
            m, J = self.node_masses[link.name]
            F = np.empty(acc[link.name].shape[:-1] + (3,))
            F[..., :2] = -m[:, None] * acc[link.name]
            F[..., 2] = -J * alpha[link.name][:, None]
            loads[link.name] = F
        # The instantaneous structure needs lengths exact to 1e-9: close the loop at C by
        # intersecting the circle about B with the rocker's circle about D or with the slide line
        # (a shift of the size of loop_closure_m).
        A, B = nodes["crank"][:, 0], nodes["coupler"][:, 0]
        near = 0.5 * (nodes["coupler"][:, -1] + self._closure_point)
        if self.slider:
            gam = mech.ground_angle
            e = np.array([math.cos(gam), math.sin(gam)])
            foot = np.asarray(mech.pivot, float) + mech.offset_m * np.array([-math.sin(gam), math.cos(gam)])
            C = _line_point(B, mech.coupler.length_m, foot, e, near)
            joints = {"A": A, "B": B, "C": C}
        else:
            D = nodes["rocker"][:, 0]
            C = _circle_point(B, mech.coupler.length_m, D, mech.rocker.length_m, near)
            joints = {"A": A, "B": B, "C": C, "D": D}
        sol = solve_static(self.structure, LoadCase(joints, loads))
        return {g.name: gauge_strains(sol.members[g.link], g) for g in self.scenario.gauges}


def _circle_point(P, r, Q, s, near) -> np.ndarray:
    """The intersection of circles (P, r) and (Q, s) nearest to ``near``, arrays (k, 2) [m]."""
    d = Q - P
    L = np.linalg.norm(d, axis=-1, keepdims=True)
    u = d / L
    x = (L**2 + r**2 - s**2) / (2 * L)
    y = np.sqrt(np.maximum(r**2 - x**2, 0.0))
    n = np.stack([-u[:, 1], u[:, 0]], -1)
    side = np.sign(np.sum((near - P) * n, -1, keepdims=True))
    return P + x * u + side * y * n


def _line_point(P, r, foot, e, near) -> np.ndarray:
    """The point of the line foot + s e at distance r from P nearest to ``near`` (k, 2) [m]."""
    rel = P - foot
    s0 = rel @ e
    h2 = np.sum(rel * rel, -1) - s0**2
    half = np.sqrt(np.maximum(r**2 - h2, 0.0))
    s_near = (near - foot) @ e
    s = np.where(np.abs(s0 + half - s_near) <= np.abs(s0 - half - s_near), s0 + half, s0 - half)
    return foot + s[:, None] * e
