"""MuJoCo engine: the rigid linkage as a reference for the flexible engines.

Model (MJCF generated from the scenario's mechanism through :func:`tmm_core.linkage.as_linkage`,
one builder for the four-bar, the slider-crank and every ``type = "linkage"`` mechanism): one
body per kinematic body of the linkage (a link, the parts of a link with interior joints, a
plate, a slider block with the links welded to it), arranged as a tree by the linkage's
closed-form modules. The crank hangs from the world on a hinge at its pivot; each dyad (rrr)
hangs its two links from the bodies that carry their known joints on hinges there and closes
its loop at the new joint with an equality ``connect``; each rrp hangs its link on a hinge and
closes the loop on a block (a light block body on a slide joint along the ground line, or the
kinematic block body on a slide joint along its guide body). ``connect``: solref =
solref_factor * dt, dampratio 1 (MuJoCo's refsafe raises a time constant below 2 dt to 2 dt);
solimp = (s, s, 0.001, 0.5, 2). Each body's frame sits at the start joint of its first link with
local x along it (a plate: at its centre of mass, x towards its first vertex); the crank's frame
is turned by the crank's zero direction (the ground angle), so the crank hinge angle *is* the
crank angle. Mass, centre of mass and z inertia of every body are the exact rigid-body values
of its links (:func:`link_inertia`) and plates. Sites sit at every mesh node of every link.
Springs are spatial tendons (stiffness, spring length); constant loads are ``general``
actuators on the loaded node's site with a world reference site (world-frame force and
moment), their control held at 1. Contacts are off (there are no geoms).

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
node positions (node sites), extras ``<link>_angle_rad`` for every link but the crank (global
angle of the link's local x axis, CCW from global X, not wrapped, as
:attr:`tmm_core.LinkMotion.angle`), ``slider_position_m`` (a single ground slide: the block's
position along it from the foot of the crank pivot) and ``loop_closure_m`` (the largest distance
between the two sites of a ``connect``: the soft constraints' own error), and the rigid
("quasi-static") gauge strains: D'Alembert loads from MuJoCo's own node accelerations (plus the
constant loads and the springs) on the instantaneous structure, solved linearly by
:func:`tmm_core.solve_static`, with the joints where the closed-form kinematics puts them at
MuJoCo's crank angle (the structure needs exact link lengths; they differ from MuJoCo's own
joint positions by the size of ``loop_closure_m``).

Owns: the MuJoCo engine: MJCF, servo or motor torque, stepping, rigid strains. Boundaries: no
kinematics of its own: loops close with tmm_core's closed-form modules.
"""
from __future__ import annotations

import math

import mujoco
import numpy as np
from mujoco import rollout

from tmm_core import InputError, LoadCase, gauge_strains, solve_static
from tmm_core.linkage import as_linkage

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in
from .mujoco_tree import BodyTree, rot2

ARMATURE_RATIO = 10.0      # armature / largest reflected linkage inertia at the crank
SERVO_STEPS = 20.0         # default servo period in internal steps: f_servo = 1 / (20 dt)
SERVO_GROUP, MOTOR_GROUP, LOAD_GROUP = 1, 2, 3


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

    def export_model(self, path) -> None:
        """Write the MJCF this engine simulates (after ``reset``) to ``path``, with a thin capsule
        between consecutive node sites of every body so MuJoCo's viewer shows the linkage
        (``python -m mujoco.viewer --mjcf=model.xml``). The capsules are visual only: no contact,
        no mass (each body keeps its explicit ``<inertial>``); every other value is the text
        simulated, digit for digit."""
        import xml.etree.ElementTree as ET
        root = ET.fromstring(self.xml)
        for body in root.iter("body"):
            pos = [np.array(s.get("pos", "0 0 0").split(), dtype=float) for s in body.findall("site")]
            for a, b in zip(pos, pos[1:]):
                if np.linalg.norm(a - b) > 1e-9:       # a capsule needs a length
                    ET.SubElement(body, "geom", type="capsule", fromto=_f(*a, *b), size="0.003", contype="0",
                                  conaffinity="0", mass="0", group="1")
        ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=False)

    @property
    def internal_step_s(self) -> float:
        if self._dt is None:
            raise EngineError("mujoco: reset() the engine before asking for its step")
        return self._dt

    # -- model --------------------------------------------------------------------------------
    def _member_sites(self) -> dict:
        """A site at every station of every member (``self.member_sites``: link -> site names);
        returns the sites per body, ``{body: [(name, local position [m])]}``."""
        lk, tree, kin = self.lk, self.tree, self.lk.kinematics
        self.member_sites = {}
        sites_of = {}
        for i, (link, a, b, _, _) in enumerate(lk.members):
            body = lk.frames[link.name]
            d = kin.reference_position(b) - kin.reference_position(a)
            e = d / np.hypot(*d)
            names = []
            for k, x in enumerate(link.stations):
                name = f"m{i}_n{k}"
                sites_of.setdefault(body, []).append((name, tree.local(body, kin.reference_position(a) + x * e)))
                names.append(name)
            self.member_sites[link.name] = names
        return sites_of

    def _joint_site(self, sites_of: dict, body, j) -> str:
        """The site at joint ``j`` on ``body``, added to ``sites_of`` the first time it is asked for."""
        key = (body, j)
        if key not in self.joint_sites:
            name = f"j{len(self.joint_sites)}"
            self.joint_sites[key] = name
            position = self.tree.local(body, self.lk.kinematics.reference_position(j))
            sites_of.setdefault(body, []).append((name, position))
        return self.joint_sites[key]

    def _spring_tendons(self, sites_of: dict, world_sites: list) -> list:
        """A spatial tendon per spring between its two joints (a grounded end gets a world site,
        appended to ``world_sites``)."""
        kin, tendons = self.lk.kinematics, []
        for sp in self.lk.springs:
            ends = []
            for j in (sp.a, sp.b):
                if j in kin.ground:
                    name = f"g_{len(world_sites)}"
                    world_sites.append(f'<site name="{name}" pos="{_f(*kin.reference_position(j), 0)}"/>')
                    ends.append(name)
                else:
                    ends.append(self._joint_site(sites_of, next(b for b in self.tree.order if j in kin.bodies[b]), j))
            tendons.append(f'<spatial name="spring_{sp.name}" stiffness="{sp.k:.17g}" '
                           f'springlength="{sp.free_length:.17g}"><site site="{ends[0]}"/><site site="{ends[1]}"/>'
                           '</spatial>')
        return tendons

    def _load_actuators(self) -> list:
        """A fixed-gear actuator per loaded member node (force [N] and moment [N m] in the world
        frame, switched on through its control); ``self.n_loads`` counts them."""
        loads = []
        for name, F in self.lk.loads.items():
            for k in np.flatnonzero(np.any(np.asarray(F) != 0, axis=-1)):
                site = self.member_sites[name][k]
                loads.append(f'<general name="load_{len(loads)}" site="{site}" refsite="world_ref" '
                             f'group="{LOAD_GROUP}" gear="{_f(F[k][0], F[k][1], 0, 0, 0, F[k][2])}"/>')
        self.n_loads = len(loads)
        return loads

    def _body_xml(self, body, parent, children: dict, sites_of: dict) -> str:
        """``body`` and its subtree: its frame relative to ``parent``, its joint, inertial and sites."""
        tree, kin = self.tree, self.lk.kinematics
        O, phi = tree.frame[body]
        if parent is None:
            pos, euler = O, (kin.crank_zero if body == kin.crank else phi)
        else:
            Op, php = tree.frame[parent]
            pos, euler = rot2(-php) @ (O - Op), phi - php
        kind = tree.joint[body]
        if body == kin.crank:
            # The crank's frame is turned by its zero direction: its hinge angle is the crank angle.
            jxml = f'<joint name="{body}_hinge" type="hinge" axis="0 0 1" armature="{self.armature:.17g}"/>'
        elif kind[0] == "hinge":
            anchor = tree.local(body, kin.reference_position(kind[1]))
            jxml = f'<joint name="{body}_hinge" type="hinge" axis="0 0 1" pos="{_f(*anchor, 0)}"/>'
        else:
            axis = rot2(-phi) @ kind[2]
            jxml = f'<joint name="{body}_slide" type="slide" axis="{_f(axis[0], axis[1], 0)}"/>'
        m, c, J = tree.mass[body]
        sites = sites_of.get(body, [])
        # Planar: only the z inertia acts; x/y values only have to pass the triangle inequality.
        return (f'<body name="{body}" pos="{_f(*pos, 0)}" euler="{_f(0, 0, euler)}">{jxml}'
                f'<inertial pos="{_f(*c, 0)}" mass="{m:.17g}" diaginertia="{_f(1e-6 * J, J, J)}"/>'
                + "".join(f'<site name="{n}" pos="{_f(*p, 0)}"/>' for n, p in sites)
                + "".join(self._body_xml(ch, body, children, sites_of) for ch in children.get(body, []))
                + '</body>')

    def _sensors(self) -> list:
        """Every body's joint position and angular acceleration, every member site's position and
        acceleration, the closure sites' positions, the crank speed and the two actuators' forces;
        ``self.hinges`` lists the hinged bodies."""
        tree, kin = self.tree, self.lk.kinematics
        sensors = []
        self.hinges = [b for b in tree.order if tree.joint[b][0] == "hinge"]
        for body in tree.order:
            jn = f"{body}_{tree.joint[body][0]}"
            sensors.append(f'<jointpos name="q_{body}" joint="{jn}"/>')
            sensors.append(f'<frameangacc name="alpha_{body}" objtype="xbody" objname="{body}"/>')
        for names in self.member_sites.values():
            for site in names:
                sensors.append(f'<framepos name="p_{site}" objtype="site" objname="{site}"/>')
                sensors.append(f'<framelinacc name="a_{site}" objtype="site" objname="{site}"/>')
        for a, b in self.closure_sites:
            for site in (a, b):
                sensors.append(f'<framepos name="p_{site}" objtype="site" objname="{site}"/>')
        return sensors + [f'<jointvel name="w_crank" joint="{kin.crank}_hinge"/>',
                          '<actuatorfrc name="f_servo" actuator="servo"/>',
                          '<actuatorfrc name="f_motor" actuator="motor"/>']

    def _mjcf(self, scenario: Scenario) -> str:
        """The MJCF of the linkage: the body tree with its sites, the closures as equality
        constraints, springs as tendons, the servo, motor and load actuators, and the sensors."""
        lk, tree, s, dt = self.lk, self.tree, scenario.mujoco, self._dt
        kin = lk.kinematics
        g = scenario.gravity or (0.0, 0.0)
        children = {}
        for body in tree.order:
            children.setdefault(tree.parent[body], []).append(body)
        sites_of = self._member_sites()
        # A site at each closure joint and spring end on the bodies that hold it.
        self.joint_sites = {}
        self.closure_sites = [(self._joint_site(sites_of, b1, j), self._joint_site(sites_of, b2, j))
                              for b1, b2, j in tree.closures]
        world_sites = ['<site name="world_ref" pos="0 0 0"/>'] + [
            f'<site name="{n}" pos="{_f(*p, 0)}"/>' for n, p in sites_of.get(None, [])]
        tendons = self._spring_tendons(sites_of, world_sites)
        loads = self._load_actuators()
        tree_xml = "".join(self._body_xml(b, None, children, sites_of) for b in children.get(None, []))
        kp, kd = self.gains
        sensors = self._sensors()
        equality = "".join(f'<connect site1="{a}" site2="{b}" solref="{_f(s.solref_factor * dt, 1)}" '
                           f'solimp="{_f(s.solimp, s.solimp, 0.001, 0.5, 2)}"/>' for a, b in self.closure_sites)
        return f"""<mujoco model="{lk.name.split(' ')[0]}">
  <compiler angle="radian"/>
  <option timestep="{dt:.17g}" integrator="Euler" gravity="{_f(g[0], g[1], 0)}">
    <flag contact="disable"/>
  </option>
  <worldbody>{''.join(world_sites)}{tree_xml}</worldbody>
  <tendon>{''.join(tendons)}</tendon>
  <equality>{equality}</equality>
  <actuator>
    <general name="servo" joint="{kin.crank}_hinge" group="{SERVO_GROUP}" gainprm="{kp:.17g}" biastype="affine"
             biasprm="{_f(0, -kp, -kd)}"/>
    <motor name="motor" joint="{kin.crank}_hinge" group="{MOTOR_GROUP}"/>
    {''.join(loads)}
  </actuator>
  <sensor>{''.join(sensors)}</sensor>
</mujoco>"""

    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float, drive_inertia_kg_m2: float = 0.0) -> None:
        """Build the model and put the linkage at crank ``angle`` [rad] turning at ``speed`` [rad/s]
        (every body from the closed-form kinematics), at time ``t0`` [s].
        ``drive_inertia_kg_m2``: a motor's rotor and flywheel inertia at the crank, carried as the
        crank's armature when driven by a torque."""
        if not (np.isfinite(drive_inertia_kg_m2) and drive_inertia_kg_m2 >= 0):
            raise EngineError(f"mujoco: drive inertia must not be negative, got {drive_inertia_kg_m2!r} kg m^2")
        self.drive_inertia = float(drive_inertia_kg_m2)
        s = scenario.mujoco
        mech = self.mech = scenario.mechanism
        try:
            lk = self.lk = as_linkage(mech)
        except InputError as exc:
            raise EngineError(f"mujoco: {exc}") from None
        self.tree = BodyTree(lk)
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
        self.node_masses = {link.name: link.node_masses() for link in mech.elastic_links()}

        st = lk.kinematics.solve(angle, speed)
        d = self.data
        tree, kin = self.tree, lk.kinematics
        for body in tree.order:
            kind = tree.joint[body]
            jid = self.model.joint(f"{body}_{kind[0]}").id
            adr, vadr = self.model.jnt_qposadr[jid], self.model.jnt_dofadr[jid]
            if body == kin.crank:
                d.qpos[adr], d.qvel[vadr] = angle, speed
            elif kind[0] == "slide":
                d.qpos[adr], d.qvel[vadr] = float(st.slides[kind[1]][0]), float(st.slides[kind[1]][1])
            else:
                bm, parent = st.bodies[body], tree.parent[body]
                pm = st.bodies.get(parent) if parent is not None else None     # a slider block does not turn
                d.qpos[adr] = _wrap(float(bm.rotation - (pm.rotation if pm else 0.0)))
                d.qvel[vadr] = float(bm.omega - (pm.omega if pm else 0.0))
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
        ctrl = np.zeros((n + 1, 2 + self.n_loads))
        ctrl[:, 2:] = 1.0                     # the constant loads
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
        lk, tree, kin = self.lk, self.tree, self.lk.kinematics
        q_crank = S(f"q_{kin.crank}")[:, 0]
        # Each body's rotation from the reference configuration: the crank's, plus the hinges down
        # the tree (slides do not turn).
        rotation = {}
        for body in tree.order:
            parent = tree.parent[body]
            if body == kin.crank:
                rotation[body] = q_crank - kin.reference_crank_angle
            else:
                base = rotation[parent] if parent is not None else 0.0
                rotation[body] = base + (S(f"q_{body}")[:, 0] if tree.joint[body][0] == "hinge" else 0.0)
        alpha = {body: S(f"alpha_{body}")[:, 2] for body in tree.order}   # absolute angular accelerations about z
        torque = S("f_servo")[:, 0] + S("f_motor")[:, 0] - self.model.dof_armature[0] * alpha[kin.crank]
        nodes, acc = {}, {}
        for link in self.mech.links():
            sites = self.member_sites[link.name]
            nodes[link.name] = np.stack([S(f"p_{site}")[:, :2] for site in sites], 1)
            acc[link.name] = np.stack([S(f"a_{site}")[:, :2] for site in sites], 1)
        extras = {}
        for link, a, b, _, _ in lk.members:
            if lk.frames[link.name] == kin.crank:
                continue
            d = kin.reference_position(b) - kin.reference_position(a)
            extras[f"{link.name}_angle_rad"] = ("rad", math.atan2(d[1], d[0]) + rotation[lk.frames[link.name]])
        if len(tree.slider_blocks) == 1:
            body, j = next(iter(tree.slider_blocks.items()))
            gam = tree.frame[body][1]
            e = np.array([math.cos(gam), math.sin(gam)])
            foot = float((kin.reference_position(j) - kin.reference_position(kin.pivot)) @ e)
            extras["slider_position_m"] = ("m", foot + S(f"q_{body}")[:, 0])
        if self.closure_sites:
            extras["loop_closure_m"] = ("m", np.max([np.linalg.norm(S(f"p_{a}")[:, :2] - S(f"p_{b}")[:, :2], axis=-1)
                                                     for a, b in self.closure_sites], axis=0))
        link_alpha = {link.name: alpha[lk.frames[link.name]] for link in self.mech.links()}
        gauges = self._rigid_strains(q_crank, acc, link_alpha)
        return EngineOutput(t, q_crank, S("w_crank")[:, 0], torque, gauges, nodes, extras)

    def _rigid_strains(self, q_crank, acc, alpha) -> dict:
        """Quasi-static gauge strains of the rigid motion, all samples in one linear solve.

        MuJoCo's ``framelinacc`` is a proper acceleration (a - g, as an accelerometer reads), so
        the D'Alembert-plus-gravity node force m (g - a) is -m times the sensor reading; the
        node moment is -J alpha. The constant loads are added; the springs act through the
        instantaneous structure (preload from its geometry)."""
        if not self.scenario.gauges:
            return {}
        mech = self.mech
        motion = mech.motion(q_crank)
        applied = mech.external_loads(motion)
        loads = {}
        for link in mech.elastic_links():
            m, J = self.node_masses[link.name]
            F = np.empty(acc[link.name].shape[:-1] + (3,))
            F[..., :2] = -m[:, None] * acc[link.name]
            F[..., 2] = -J * alpha[link.name][:, None]
            if link.name in applied:
                F = F + applied[link.name]
            loads[link.name] = F
        sol = solve_static(self.structure, LoadCase(mech.joint_positions(motion), loads))
        return {g.name: gauge_strains(sol.members[g.link], g) for g in self.scenario.gauges}
