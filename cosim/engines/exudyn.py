"""exudyn flexible-body engine: the same linkage with planar ANCF cable elements.

Element choice: ``ObjectANCFCable2D`` (Euler-Bernoulli, geometrically exact in the plane, cubic
in position with slope vectors at the nodes). It is the same beam theory as the transfer-matrix
model and, in exudyn 1.13, needs about a quarter of the elements of the linear geometrically
exact 2D beam for the same midspan strain (docs/validation.md, "Reference engines: modelling choices"). The mesh of each link: one
element per end block plus ``solver.exudyn.elements`` over the span.

One builder for every mechanism (:func:`tmm_core.linkage.as_linkage`: the four-bar, the
slider-crank and every ``type = "linkage"``): one cable chain per link part, joined joint by
joint. Joints are planar: ``RevoluteJoint2D`` between the members that meet at a revolute, the
plate vertices and the ground pivots (3D joints over-constrain a closed planar loop, exudyn issue
#39); welded ends (interior joints of a link, links welded to a slider block) are
``GenericJoint`` s constraining x, y and the relative rotation about z. The crank's root node is
clamped to a light rigid hub at its pivot (exudyn issue #1); the hub is pinned to the ground and
either follows a prescribed angle (a coordinate constraint whose reaction is the drive torque) or
carries an applied torque. A rigid crank and each plate are rigid bodies with their exact mass
properties; a ground slide is a light block on a ``ObjectJointPrismatic2D`` to the ground, and a
block on a moving guide one on a prismatic joint to the guide cable's tangent at its guide joint
(the transfer-matrix model's sliding joint). Springs are ``ObjectConnectorSpringDamper`` s,
constant loads ``LoadForceVector`` s on the loaded nodes. With springs or loads the run starts
from the static equilibrium under them (``SolveStatic`` with the crank held), as the
transfer-matrix model starts from its quasi-static state.

Damping: exudyn's cable damping is material (Kelvin-Voigt): ``bendingDamping = beta EI`` and
``axialDamping = beta EA`` with the link's stiffness-proportional coefficient beta, the same
law as the transfer-matrix engine. Mass-proportional damping and rotary inertia of point masses
have no equivalent on cable nodes and are refused.

Integrator: generalized-alpha with ``spectral_radius`` (default 0.9), fixed step, modified
Newton with relative tolerance ``newton_tolerance`` (1e-8 sits at round-off for stiff axial
members and makes the adaptive step collapse; docs/validation.md, "Reference engines: modelling choices"), sparse linear solver.

Outputs are sampled once per macro step, at its end: crank angle and speed, drive torque,
gauge strains (curvature and axial strain of the cable; at a node between two elements the two
neighbours are averaged, because cable curvature jumps there), and all node positions.

Owns: the exudyn engine: model build, stepping, save/restore, sampled outputs. Boundaries: no
scenario parsing (it reads a Scenario) and no files except the solution file it is asked for.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

import exudyn as exu
from exudyn.itemInterface import (CoordinateConstraint, GenericJoint, LoadCoordinate, LoadForceVector,
                                  LoadMassProportional, MarkerBodyMass, MarkerBodyPosition, MarkerBodyRigid,
                                  LoadTorqueVector, MarkerNodeCoordinate, MarkerNodePosition, NodePoint2DSlope1,
                                  NodePointGround, NodeRigidBody2D, ObjectANCFCable2D, ObjectConnectorSpringDamper,
                                  ObjectGround, ObjectJointPrismatic2D, ObjectMassPoint2D, ObjectRigidBody2D,
                                  RevoluteJoint2D, SensorBody, SensorNode, SensorObject)

from tmm_core import InputError
from tmm_core.linkage import as_linkage

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in

from .exudyn_bodies import HUB_INERTIA_KG_M2, HUB_MASS_KG, OVT, light_block, rigid_link, rz


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


class ExudynEngine:
    name = "exudyn"
    kinematic = False

    def __init__(self):
        self._h = None
        self._drive = None
        self._solution = None         # (path, period [s]) of write_solution

    def write_solution(self, path, period_s: float = 2e-3) -> None:
        """During the run, write the system coordinates every ``period_s`` [s] of simulated time
        to ``path`` in exudyn's own solution-file format (one file over all macro steps), to
        replay the run in exudyn's viewer: ``exudyn.interactive.SolutionViewer(engine.mbs,
        exudyn.utilities.LoadSolutionFile(path))`` with an engine reset on the same scenario."""
        if not period_s > 0:
            raise ValueError(f"write_solution: period_s must be positive, got {period_s!r}")
        self._solution = (str(path), float(period_s))

    @property
    def internal_step_s(self) -> float:
        if self._h is None:
            raise EngineError("exudyn: reset() the engine before asking for its step")
        return self._h

    # -- model ---------------------------------------------------------------------------------
    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float, drive_inertia_kg_m2: float = 0.0) -> None:
        """Build the model at crank ``angle`` [rad] and ``speed`` [rad/s] at ``t0`` [s];
        ``drive_inertia_kg_m2`` (a motor's rotor and flywheel at the crank) sits on the hub."""
        if not (np.isfinite(drive_inertia_kg_m2) and drive_inertia_kg_m2 >= 0):
            raise EngineError(f"exudyn: drive inertia must not be negative, got {drive_inertia_kg_m2!r} kg m^2")
        self._hub_inertia = HUB_INERTIA_KG_M2 + float(drive_inertia_kg_m2)
        self._speed0 = speed
        settings = scenario.exudyn
        mech = scenario.mechanism
        try:
            lk = as_linkage(mech)
        except InputError as exc:
            raise EngineError(f"exudyn: {exc}") from None
        self._carriers = {p.carrier: p for p in lk.plates}
        links = [l if (l.rigid or l.name in self._carriers) else dataclasses.replace(l, n_segments=settings.elements)
                 for l in mech.links()]
        for link in links:
            if link.rigid or link.name in self._carriers:   # rigid bodies with exact mass properties
                continue
            if link.damping.mass_per_s > 0:
                raise EngineError(f"exudyn: link '{link.name}' has mass-proportional damping, which the cable "
                                  "elements cannot represent; use stiffness-proportional (modal) damping")
            for pm in link.point_masses:
                if pm.inertia_kg_m2 > 0:
                    raise EngineError(f"exudyn: point mass '{pm.label}' on '{link.name}' has rotary inertia, which a "
                                      "cable node cannot carry; model it as an end block")
            if link.viscoelastic is not None:
                raise EngineError(f"exudyn: link '{link.name}' is viscoelastic; the cable elements are elastic "
                                  "(use the transfer-matrix engine)")
        self.scenario, self.links = scenario, {l.name: l for l in links}
        self._h = settings.step_s
        self.t0, self.k = t0, 0
        self.gauges = scenario.gauges
        self._build(lk, angle, speed, scenario.gravity)
        self._preloaded = bool(lk.springs or lk.loads)
        self._init_solver(settings)

    def _build(self, lk, angle, speed, gravity):
        """The model of a linkage (:func:`tmm_core.linkage.as_linkage`): one cable chain per link
        part, rigid bodies for a rigid crank, plates and slider blocks, joined joint by joint."""
        mo = lk.motion(np.array([float(angle)]), speed, 0.0)
        joints = _Joints(lk.kinematics)
        self._hub(lk, mo, angle, speed, joints)
        station_sensors, node_markers = self._links(lk, mo, gravity, joints)
        self._plates(lk, mo, gravity, joints, station_sensors)
        self._slides(lk, mo, joints)
        joints.join(self.mbs, self._ground)
        self._springs_and_loads(lk, joints, node_markers)
        self._gauge_sensors = {g.name: self._gauge(g) for g in self.gauges}
        self._output_sensors(station_sensors)
        self.mbs.Assemble()

    def _hub(self, lk, mo, angle, speed, joints):
        """The system, the ground and the crank hub: pinned at the crank pivot, its rotation
        prescribed through a coordinate constraint (or driven by a torque)."""
        kin = lk.kinematics
        SC = exu.SystemContainer()
        mbs = SC.AddSystem()
        self._sc, self.mbs = SC, mbs
        self._ground = mbs.AddObject(ObjectGround())
        gnode = mbs.AddNode(NodePointGround())
        mg = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=gnode, coordinate=0))
        A = kin.reference_position(kin.pivot)
        crank_global = float(mo.link(lk.crank.name).angle[0])
        self._angle0 = float(angle)
        hub_node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[A[0], A[1], crank_global],
                                               initialVelocities=[0.0, 0.0, speed]))
        self._hub_node = hub_node
        hub = mbs.AddObject(ObjectRigidBody2D(nodeNumber=hub_node, mass=HUB_MASS_KG, inertia=self._hub_inertia))
        hc = [mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=hub_node, coordinate=i)) for i in range(3)]
        mbs.AddObject(CoordinateConstraint(markerNumbers=[mg, hc[0]]))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[mg, hc[1]]))
        # Crank drive: the hub rotation (relative to its reference angle) follows the prescribed
        # angle; in torque mode the constraint is switched off and a torque acts on the coordinate.
        self._drive_constraint = mbs.AddObject(CoordinateConstraint(
            markerNumbers=[mg, hc[2]], offsetUserFunction=self._offset, offsetUserFunction_t=self._offset_t))
        self._torque_load = mbs.AddLoad(LoadCoordinate(markerNumber=hc[2], loadUserFunction=self._torque))
        joints.attach(kin.pivot, mbs.AddMarker(MarkerBodyPosition(bodyNumber=hub, localPosition=[0, 0, 0])),
                      (hub, [0.0, 0.0, 0.0]), crank_global, "owner")

    def _links(self, lk, mo, gravity, joints):
        """Each link part as a chain of ANCF cables (a rigid one as a rigid body), with its point
        masses and gravity; returns the station sensors and node markers by link."""
        mbs = self.mbs
        attach = joints.attach
        self.nodes, self.elements, station_sensors, node_markers = {}, {}, {}, {}
        for link0, a, b, ca, cb in lk.members:
            if link0.name in self._carriers:
                continue
            link = self.links[link0.name]
            lm = mo.link(link.name)
            phi = float(lm.angle[0])
            if link.rigid:
                ends, start_rigid, station_sensors[link.name] = rigid_link(mbs, link, mo, gravity)
                attach(a, ends[0], start_rigid, phi, "weld" if ca == "rigid" else "pin")
                attach(b, ends[1], None, phi, "pin")
                continue
            c, s = math.cos(phi), math.sin(phi)
            pos, vel, _ = lm.point(link.stations)
            w = float(lm.omega[0])
            nodes = [mbs.AddNode(NodePoint2DSlope1(referenceCoordinates=[p[0], p[1], c, s],
                                                   initialVelocities=[v[0], v[1], -w * s, w * c]))
                     for p, v in zip(pos[0], vel[0])]
            member = link.member("a", "b")
            mu = link.segment_mass_per_length()
            beta = link.damping.stiffness_s
            elems = [mbs.AddObject(ObjectANCFCable2D(
                length=L, massPerLength=mu[j], bendingStiffness=member.EI[j], axialStiffness=member.EA[j],
                bendingDamping=beta * member.EI[j], axialDamping=beta * member.EA[j],
                nodeNumbers=[nodes[j], nodes[j + 1]])) for j, L in enumerate(member.segment_lengths)]
            for pm in link.point_masses:
                j = int(np.argmin(np.abs(link.stations - pm.position_m)))
                mbs.AddObject(ObjectMassPoint2D(nodeNumber=nodes[j], mass=pm.mass_kg))
                if gravity is not None:
                    mbs.AddLoad(LoadForceVector(markerNumber=mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[j])),
                                                loadVector=[pm.mass_kg * gravity[0], pm.mass_kg * gravity[1], 0.0]))
            if gravity is not None:
                for e in elems:
                    mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=e)),
                                                     loadVector=[gravity[0], gravity[1], 0.0]))
            self.nodes[link.name], self.elements[link.name] = nodes, elems
            node_markers[link.name] = [mbs.AddMarker(MarkerNodePosition(nodeNumber=n)) for n in nodes]
            rig = ((elems[0], [0.0, 0.0, 0.0]), (elems[-1], [member.segment_lengths[-1], 0.0, 0.0]))
            attach(a, node_markers[link.name][0], rig[0], phi, "weld" if ca == "rigid" else "pin")
            attach(b, node_markers[link.name][-1], rig[1], phi, "weld" if cb == "rigid" else "pin")
            station_sensors[link.name] = [mbs.AddSensor(SensorNode(nodeNumber=n, storeInternal=True, writeToFile=False,
                                                                   outputVariableType=OVT.Position)) for n in nodes]
        return station_sensors, node_markers

    def _plates(self, lk, mo, gravity, joints, station_sensors):
        """Plates: one rigid body at the centre of mass (reference angle 0), pinned at its vertices."""
        mbs, attach = self.mbs, joints.attach
        for p in lk.plates:
            pc, vc, _ = mo.joint(p.master)
            om = float(mo.state.bodies[lk.frames[p.carrier]].omega[0])
            node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[pc[0, 0], pc[0, 1], 0.0],
                                               initialVelocities=[vc[0, 0], vc[0, 1], om]))
            body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=node, mass=p.mass_kg, inertia=p.inertia_kg_m2))
            if gravity is not None:
                mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=body)),
                                                 loadVector=[gravity[0], gravity[1], 0.0]))
            for v in p.vertices:
                rel = mo.position(v)[0] - pc[0]
                attach(v, mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[rel[0], rel[1], 0.0])))
            carrier = self.links[p.carrier]
            lm = mo.link(p.carrier)
            rel = lm.point(carrier.stations)[0][0] - pc[0]
            station_sensors[p.carrier] = [mbs.AddSensor(SensorBody(bodyNumber=body, localPosition=[x, y, 0.0],
                                                                   storeInternal=True, writeToFile=False,
                                                                   outputVariableType=OVT.Position)) for x, y in rel]

    def _slides(self, lk, mo, joints):
        """Slider blocks on the ground and on moving guides."""
        mbs, attach, ground, kin = self.mbs, joints.attach, self._ground, lk.kinematics
        # Ground slides: a light block on a planar prismatic joint along the guide; the block's mass
        # is a point mass on the link end (as in the other engines).
        for j, gam in kin.ground_slides.items():
            e = np.array([math.cos(gam), math.sin(gam)])
            P, vP, _ = mo.joint(j)
            body = light_block(mbs, P[0], vP[0], gam, 0.0)
            mbs.AddObject(ObjectJointPrismatic2D(
                markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[P[0, 0], P[0, 1], 0.0])),
                               mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, localPosition=[0.0, 0.0, 0.0]))],
                axisMarker0=[e[0], e[1], 0.0], normalMarker1=[0.0, 1.0, 0.0], constrainRotation=True))
            attach(j, mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0, 0, 0])),
                   (body, [0.0, 0.0, 0.0]), gam, "owner")
        # Blocks on a moving guide: a light block on a prismatic joint along the guide's tangent at
        # its guide joint (the guide's cross-section there: the transfer-matrix model's sliding joint).
        for sl in lk.sliders:
            ga, gb, _, _ = lk.member_ends(sl.along)
            guide = self.links[sl.along]
            phi = float(mo.link(sl.along).angle[0])
            elems = self.elements[sl.along]
            m0 = (mbs.AddMarker(MarkerBodyRigid(bodyNumber=elems[0], localPosition=[0, 0, 0])) if sl.guide == ga else
                  mbs.AddMarker(MarkerBodyRigid(bodyNumber=elems[-1],
                                                localPosition=[guide.member("a", "b").segment_lengths[-1], 0, 0])))
            P, vP, _ = mo.joint(sl.block)
            body = light_block(mbs, P[0], vP[0], phi, float(mo.link(sl.along).omega[0]))
            mbs.AddObject(ObjectJointPrismatic2D(
                markerNumbers=[m0, mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, localPosition=[0.0, 0.0, 0.0]))],
                axisMarker0=[1.0, 0.0, 0.0], normalMarker1=[0.0, 1.0, 0.0], constrainRotation=True))
            attach(sl.block, mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0, 0, 0])),
                   (body, [0.0, 0.0, 0.0]), phi, "owner")

    def _springs_and_loads(self, lk, joints, node_markers):
        """Springs between joints, and the constant loads at the link nodes."""
        mbs = self.mbs
        for sp in lk.springs:
            ends = [joints.marker(j, mbs, self._ground) for j in (sp.a, sp.b)]
            mbs.AddObject(ObjectConnectorSpringDamper(markerNumbers=ends, referenceLength=sp.free_length,
                                                      stiffness=sp.k))
        for name, F in lk.loads.items():
            tmm_stations = next(l for l in lk.links() if l.name == name).stations
            own = self.links[name].stations
            for k in np.flatnonzero(np.any(np.asarray(F) != 0, axis=-1)):
                i = int(np.argmin(np.abs(own - tmm_stations[k])))
                if abs(own[i] - tmm_stations[k]) > 1e-9 * own[-1]:
                    raise EngineError(f"exudyn: the load on '{name}' at {tmm_stations[k]:.6g} m is at no node of its "
                                      f"{len(own) - 1} elements")
                mbs.AddLoad(LoadForceVector(markerNumber=node_markers[name][i], loadVector=[F[k][0], F[k][1], 0.0]))
                if F[k][2]:
                    e = min(i, len(self.elements[name]) - 1)
                    x = own[i] - own[e]
                    mbs.AddLoad(LoadTorqueVector(markerNumber=mbs.AddMarker(MarkerBodyRigid(
                        bodyNumber=self.elements[name][e], localPosition=[x, 0, 0])), loadVector=[0.0, 0.0, F[k][2]]))

    def _gauge(self, g) -> tuple:
        """A gauge's sensors: the element(s) around its position (curvature and strain), its
        section depth [m] and face."""
        mbs = self.mbs
        link = self.links[g.link]
        st = link.stations
        j = int(np.argmin(np.abs(st - g.position_m)))
        sensors = []
        if abs(st[j] - g.position_m) < 1e-9 * link.length_m:
            spots = [(j - 1, st[j] - st[j - 1])] if j > 0 else []
            spots += [(j, 0.0)] if j < len(st) - 1 else []
        else:
            e = int(np.clip(np.searchsorted(st, g.position_m) - 1, 0, len(st) - 2))
            spots = [(e, g.position_m - st[e])]
        for e, x in spots:
            body = self.elements[g.link][e]
            sensors.append((mbs.AddSensor(SensorBody(bodyNumber=body, localPosition=[x, 0, 0], storeInternal=True,
                                                     writeToFile=False, outputVariableType=OVT.CurvatureLocal)),
                            mbs.AddSensor(SensorBody(bodyNumber=body, localPosition=[x, 0, 0], storeInternal=True,
                                                     writeToFile=False, outputVariableType=OVT.StrainLocal))))
        sec = link.member("a", "b").sections[min(j, link.total_segments - 1)]
        return sensors, sec.depth_m, g.face

    def _output_sensors(self, station_sensors):
        """The hub's, the drive's and the stations' sensors."""
        mbs = self.mbs
        # Every output is sampled at every internal step (stored in memory by exudyn for one
        # SolveDynamic): sampling only at macro-step ends under-resolves the strain peaks (at 72
        # macro steps per revolution a 13th-harmonic vibration loses up to 15 % of its peak, and a
        # macro step that is not a divisor of the period makes the loss change from revolution to
        # revolution, so no steady state is ever seen).
        def stored(**kw):
            return mbs.AddSensor(SensorNode(storeInternal=True, writeToFile=False, **kw))
        self._hub_sensors = [stored(nodeNumber=self._hub_node, outputVariableType=o)
                             for o in (OVT.Coordinates, OVT.Coordinates_t, OVT.Coordinates_tt)]
        self._drive_sensor = mbs.AddSensor(SensorObject(objectNumber=self._drive_constraint, storeInternal=True,
                                                        writeToFile=False, outputVariableType=OVT.Force))
        self._node_sensors = station_sensors

    def _init_solver(self, settings):
        sims = exu.SimulationSettings()
        ti = sims.timeIntegration
        ti.numberOfSteps = 1
        ti.startTime = 0.0
        ti.endTime = self._h
        ti.generalizedAlpha.spectralRadius = settings.spectral_radius
        ti.newton.relativeTolerance = settings.newton_tolerance
        ti.newton.useModifiedNewton = False
        ti.adaptiveStep = False
        ti.verboseMode = 0
        sims.solution.file.write = False
        sims.solution.sensors.active = True       # needed for storeInternal; every sensor has writeToFile=False
        sims.solution.sensors.writePeriod = 0.5 * self._h     # every step, once (robust to round-off)
        sims.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        self.sims = sims
        self._drive = DriveInput(prescribed=lambda t: (np.asarray(self._angle0 + 0.0 * np.asarray(t)), 0.0, 0.0))
        if self._preloaded:
            self._static_start()

    def _static_start(self):
        """Start from the static equilibrium under the springs and constant loads (the crank held
        at its start angle), with the rigid-body velocities: the analogue of the transfer-matrix
        model's quasi-static start. Switched on suddenly on the undeformed linkage, a preload of
        hundreds of newtons rings in the stiff modes hard enough to stop Newton at the first steps."""
        sims = exu.SimulationSettings()
        sims.solution.file.write = False
        sims.solution.sensors.active = False
        sims.staticSolver.verboseMode = 0
        sims.staticSolver.newton.relativeTolerance = 1e-9
        sims.staticSolver.numberOfLoadSteps = 1
        sims.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        sd = self.mbs.systemData
        init = exu.ConfigurationType.Initial
        v0 = np.array(sd.GetODE2Coordinates_t(init), copy=True)
        try:
            exu.SolveStatic(self.mbs, sims, updateInitialValues=True)
        except Exception as exc:   # exudyn raises its own SolverError after printing its diagnosis
            raise EngineError(f"exudyn: the static start under the springs and loads did not converge "
                              f"({exc})") from None
        for config in (init, exu.ConfigurationType.Current):
            sd.SetODE2Coordinates_t(v0, config)

    # -- user functions (called by exudyn; time is exudyn's local time from 0) -----------------
    def _offset(self, mbs, t, item, offset):
        return float(np.asarray(self._drive.prescribed(self.t0 + t)[0])) - self._angle0

    def _offset_t(self, mbs, t, item, offset):
        return float(np.asarray(self._drive.prescribed(self.t0 + t)[1]))

    def _torque(self, mbs, t, load):
        return 0.0 if self._drive.torque is None else float(self._drive.torque_at(self.t0 + t))

    def _set_mode(self, prescribed: bool):
        self.mbs.SetObjectParameter(self._drive_constraint, "activeConnector", prescribed)

    def node_stations(self) -> dict:
        """Local x [m] of the nodes this engine reports (its own mesh), per link."""
        return {name: link.stations for name, link in self.links.items()}

    def initial_output(self) -> EngineOutput:
        return EngineOutput(np.array([self.t0]), np.array([self._angle0]), np.array([self._speed0]), np.array([np.nan]))

    def save(self):
        """The state the next SolveDynamic starts from (its initial configuration), with the
        accelerations the generalized-alpha start uses."""
        sd = self.mbs.systemData
        init = exu.ConfigurationType.Initial
        return (self.k, self._drive, [np.array(v, copy=True) for v in sd.GetSystemState(init)],
                np.array(sd.GetODE2Coordinates_tt(init), copy=True))

    def restore(self, token) -> None:
        self.k, drive, state, acc = token
        if (drive.prescribed is not None) != (self._drive.prescribed is not None):
            self._set_mode(drive.prescribed is not None)
        self._drive = drive
        sd = self.mbs.systemData
        for config in (exu.ConfigurationType.Initial, exu.ConfigurationType.Current):
            sd.SetSystemState(state, config)
            sd.SetODE2Coordinates_tt(acc, config)

    # -- stepping ------------------------------------------------------------------------------
    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput:
        t_start = self.t0 + self.k * self._h
        n = steps_in(t_start, t_next, self._h, "exudyn")
        prescribed = drive.prescribed is not None
        if (self._drive.prescribed is not None) != prescribed:
            self._set_mode(prescribed)
        self._drive = drive
        # One SolveDynamic per macro step, continuing from the current state (updateInitialValues).
        # Resuming a persistent MainSolverImplicitSecondOrder with SolveSteps and a moved endTime was
        # tried and is not reliable in exudyn 1.13 (its time jumps back and Newton fails after a few
        # macro steps); restarting reproduces one uninterrupted solve to 4e-5 relative (measured).
        ti = self.sims.timeIntegration
        ti.startTime, ti.endTime, ti.numberOfSteps = self.k * self._h, (self.k + n) * self._h, n
        ti.generalizedAlpha.computeInitialAccelerations = self.k == 0
        if self._solution is not None:     # write_solution: each SolveDynamic appends its rows
            f = self.sims.solution.file
            f.write, (f.name, f.writePeriod) = True, self._solution
            f.append, f.writeFooter = self.k > 0, False
            f.writeHeader = f.writeInitialValues = self.k == 0
            f.export.velocities = f.export.accelerations = f.export.algebraicCoordinates = 0
        try:
            exu.SolveDynamic(self.mbs, self.sims, updateInitialValues=True)
        except Exception as exc:   # exudyn raises its own SolverError after printing its diagnosis
            if "KeyboardInterrupt" in str(exc):      # Ctrl-C inside a user function: not a Newton failure
                raise KeyboardInterrupt("interrupted in exudyn's solver") from None
            raise EngineError(f"exudyn: Newton did not converge before t = {t_next:.6g} s ({exc}); reduce "
                              "solver.exudyn.step") from None
        k0, self.k = self.k, self.k + n
        return self._samples(self.t0 + (k0 + 1 + np.arange(n)) * self._h)

    def _samples(self, t: np.ndarray) -> EngineOutput:
        """The outputs at every internal step of the last SolveDynamic (times ``t`` [s])."""
        mbs, n = self.mbs, len(t)

        def rows(sensor):
            # exudyn stores the start of each solve as well; keep the n steps after it.
            data = np.asarray(mbs.GetSensorStoredData(sensor))
            if data.ndim != 2 or len(data) < n:
                raise EngineError(f"exudyn: sensor {sensor} stored {len(data)} samples for {n} steps")
            return data[-n:, 1:]
        q, v, a = (rows(s) for s in self._hub_sensors)
        angle, speed = self._angle0 + q[:, 2], v[:, 2]
        if self._drive.prescribed is not None:
            # The constraint reaction on the hub coordinate is minus the torque the drive applies.
            torque = -rows(self._drive_sensor)[:, 0]
        else:
            torque = np.array([float(self._drive.torque_at(ti)) for ti in t])
        # The linkage takes what the hub (with the drive's inertia) does not keep.
        torque = torque - self._hub_inertia * a[:, 2]
        gauges = {}
        for name, (sensors, depth, face) in self._gauge_sensors.items():
            kappa = np.mean([rows(sk)[:, 0] for sk, _ in sensors], axis=0)
            axial = np.mean([rows(sa)[:, 0] for _, sa in sensors], axis=0)
            sign = -1.0 if face == "top" else 1.0       # CurvatureLocal is CCW positive (= w'')
            gauges[name] = (sign * kappa * 0.5 * depth, axial)
        nodes = {name: np.stack([rows(s)[:, :2] for s in ss], axis=1) for name, ss in self._node_sensors.items()}
        return EngineOutput(np.asarray(t, float), angle, speed, torque, gauges, nodes)


def natural_frequencies(scenario: Scenario, angle: float, n_modes: int = 4) -> np.ndarray:
    """First ``n_modes`` natural frequencies [Hz] of the linkage with the crank held at ``angle``
    (undamped, at rest), from exudyn's constrained eigenvalue analysis of the same model."""
    engine = ExudynEngine()
    engine.reset(scenario, 0.0, angle, 0.0)
    values, _ = engine.mbs.ComputeODE2Eigenvalues(convert2Frequencies=True, ignoreAlgebraicEquations=False)
    values = np.sort(np.asarray(values, dtype=float))
    values = values[values > 1e-3]   # the constraint projection leaves numerically zero modes [Hz]
    return values[:n_modes]


class _Joints:
    """What meets at every joint while a model is built: (position marker, (body, local position)
    of a rigid marker or None, its frame angle, kind) with kind 'owner' (a body the welded link
    ends lock to: the hub, a slider block), 'weld' (a link end welded to the joint) or 'pin' (a
    revolute: link ends, plate vertices, ground); then joined joint by joint."""

    def __init__(self, kinematics):
        self.kin = kinematics
        self.at = {}
        self._ground_markers = {}

    def attach(self, j, pos, rigid=None, frame=0.0, kind="pin"):
        self.at.setdefault(j, []).append((pos, rigid, frame, kind))

    def on_ground(self, j, mbs, ground):
        """A position marker on the ground at joint ``j`` (one per joint)."""
        if j not in self._ground_markers:
            P = self.kin.reference_position(j)
            self._ground_markers[j] = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground,
                                                                       localPosition=[P[0], P[1], 0.0]))
        return self._ground_markers[j]

    def marker(self, j, mbs, ground):
        """A position marker at joint ``j``: the first attached there, else one on the ground."""
        return self.at[j][0][0] if j in self.at else self.on_ground(j, mbs, ground)

    def join(self, mbs, ground):
        """Ground joints pinned to the ground; at every joint the owner (or first weld, else the
        first pin) carries the other welds (rigidly, at their drawn angle) and the pins."""
        kin = self.kin
        for j in kin.ground:
            if j != kin.pivot and j in self.at:       # the hub is pinned at the crank pivot already
                self.attach(j, self.on_ground(j, mbs, ground))
        for j, items in self.at.items():
            welds = [x for x in items if x[3] == "owner"] + [x for x in items if x[3] == "weld"]
            pins = [x for x in items if x[3] == "pin"]
            base = welds[0] if welds else pins.pop(0)
            for x in welds[1:]:
                # The second marker's frame is turned onto the first's: the weld keeps the angle
                # the two ends make in the drawn linkage (a kink, an arm square to its block).
                turn = _wrap(base[2] - x[2])
                m1 = (MarkerBodyRigid(bodyNumber=x[1][0], localPosition=x[1][1]) if abs(turn) < 1e-15 else
                      MarkerBodyRigid(bodyNumber=x[1][0], localHT=exu.HT(rotation=rz(turn), translation=x[1][1])))
                mbs.AddObject(GenericJoint(markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=base[1][0],
                                                                                        localPosition=base[1][1])),
                                                          mbs.AddMarker(m1)], constrainedAxes=[1, 1, 0, 0, 0, 1]))
            for x in pins:
                mbs.AddObject(RevoluteJoint2D(markerNumbers=[base[0], x[0]]))
