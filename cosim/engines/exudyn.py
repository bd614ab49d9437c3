"""exudyn flexible-body engine: the same four-bar with planar ANCF cable elements.

Element choice: ``ObjectANCFCable2D`` (Euler-Bernoulli, geometrically exact in the plane, cubic
in position with slope vectors at the nodes). It is the same beam theory as the transfer-matrix
model and, in exudyn 1.13, needs about a quarter of the elements of the linear geometrically
exact 2D beam for the same midspan strain (engine_pitfalls.md). The mesh of each link: one
element per end block plus ``solver.exudyn.elements`` over the span.

Joints are planar: ``RevoluteJoint2D`` at B and C and at the rocker pivot D (3D joints
over-constrain a closed planar loop, exudyn issue #39). The crank's root node is clamped to a
light rigid hub at A (``GenericJoint`` constraining x, y and the rotation about z, exudyn issue
#1); the hub is pinned to the ground and either follows a prescribed angle (a coordinate
constraint whose reaction is the drive torque) or carries an applied torque.

Damping: exudyn's cable damping is material (Kelvin-Voigt): ``bendingDamping = beta EI`` and
``axialDamping = beta EA`` with the link's stiffness-proportional coefficient beta, the same
law as the transfer-matrix engine. Mass-proportional damping and rotary inertia of point masses
have no equivalent on cable nodes and are refused.

Integrator: generalized-alpha with ``spectral_radius`` (default 0.9), fixed step, modified
Newton with relative tolerance ``newton_tolerance`` (1e-8 sits at round-off for stiff axial
members and makes the adaptive step collapse; engine_pitfalls.md), sparse linear solver.

Outputs are sampled once per macro step, at its end: crank angle and speed, drive torque,
gauge strains (curvature and axial strain of the cable; at a node between two elements the two
neighbours are averaged, because cable curvature jumps there), and all node positions.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

import exudyn as exu
from exudyn.itemInterface import (CoordinateConstraint, GenericJoint, LoadCoordinate, LoadForceVector,
                                  LoadMassProportional, MarkerBodyMass, MarkerBodyPosition, MarkerBodyRigid,
                                  MarkerNodeCoordinate, MarkerNodePosition, NodePoint2DSlope1, NodePointGround,
                                  NodeRigidBody2D, ObjectANCFCable2D, ObjectGround, ObjectJointPrismatic2D,
                                  ObjectMassPoint2D,
                                  ObjectRigidBody2D, RevoluteJoint2D, SensorBody, SensorNode,
                                  SensorObject)

from tmm_core import SliderCrankMechanism

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in

OVT = exu.OutputVariableType
HUB_MASS_KG = 1e-3        # the hub only transmits the drive; its own inertia must not matter
HUB_INERTIA_KG_M2 = 1e-8


class ExudynEngine:
    name = "exudyn"
    kinematic = False

    def __init__(self):
        self._h = None
        self._drive = None

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
        links = [l if l.rigid else dataclasses.replace(l, n_segments=settings.elements) for l in mech.links()]
        for link in links:
            if link.rigid:       # one rigid body with the exact mass properties: nothing to refuse
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
        self._build(mech, links, angle, speed, scenario.gravity)
        self._init_solver(settings)

    def _build(self, mech, links, angle, speed, gravity):
        SC = exu.SystemContainer()
        mbs = SC.AddSystem()
        self._sc, self.mbs = SC, mbs
        mo = mech.motion(np.array([angle]), speed, 0.0)
        ground = mbs.AddObject(ObjectGround())
        gnode = mbs.AddNode(NodePointGround())
        mg = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=gnode, coordinate=0))
        A = mo.A[0]
        self._angle0 = float(mo.crank.angle[0])
        hub_node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[A[0], A[1], self._angle0],
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

        self.nodes, self.elements = {}, {}
        # Per link: position markers at its start and end joint, and a rigid marker at its start
        # (the crank is welded to the hub there); per link the sensors of its drawn stations.
        ends, start_rigid, station_sensors = {}, {}, {}
        for link in links:
            if link.rigid:
                ends[link.name], start_rigid[link.name], station_sensors[link.name] = \
                    self._rigid_link(mbs, link, mo, gravity)
                continue
            lm = mo.link(link.name)
            c, s = math.cos(lm.angle[0]), math.sin(lm.angle[0])
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
                mp = mbs.AddObject(ObjectMassPoint2D(nodeNumber=nodes[j], mass=pm.mass_kg))
                if gravity is not None:
                    mbs.AddLoad(LoadForceVector(markerNumber=mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[j])),
                                                loadVector=[pm.mass_kg * gravity[0], pm.mass_kg * gravity[1], 0.0]))
            if gravity is not None:
                for e in elems:
                    mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=e)),
                                                     loadVector=[gravity[0], gravity[1], 0.0]))
            self.nodes[link.name], self.elements[link.name] = nodes, elems
            ends[link.name] = (mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[0])),
                               mbs.AddMarker(MarkerNodePosition(nodeNumber=nodes[-1])))
            start_rigid[link.name] = mbs.AddMarker(MarkerBodyRigid(bodyNumber=elems[0], localPosition=[0, 0, 0]))
            station_sensors[link.name] = [mbs.AddSensor(SensorNode(nodeNumber=n, storeInternal=True, writeToFile=False,
                                                                   outputVariableType=OVT.Position)) for n in nodes]

        mbs.AddObject(GenericJoint(markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=hub, localPosition=[0, 0, 0])),
                                                  start_rigid["crank"]],
                                   constrainedAxes=[1, 1, 0, 0, 0, 1]))
        mbs.AddObject(RevoluteJoint2D(markerNumbers=[ends["crank"][1], ends["coupler"][0]]))
        if isinstance(mech, SliderCrankMechanism):
            # A light block on a planar prismatic joint along the guide, pinned to the coupler's end
            # (the block's mass is the coupler end's point mass, as in the other engines).
            gam = mech.ground_angle
            e = np.array([math.cos(gam), math.sin(gam)])
            C, vC = mo.C[0], float(mo.slider_velocity[0]) * e
            block = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[C[0], C[1], gam],
                                                initialVelocities=[vC[0], vC[1], 0.0]))
            body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=block, mass=HUB_MASS_KG, inertia=HUB_INERTIA_KG_M2))
            mbs.AddObject(ObjectJointPrismatic2D(
                markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[C[0], C[1], 0.0])),
                               mbs.AddMarker(MarkerBodyRigid(bodyNumber=body, localPosition=[0.0, 0.0, 0.0]))],
                axisMarker0=[e[0], e[1], 0.0], normalMarker1=[0.0, 1.0, 0.0], constrainRotation=True))
            mbs.AddObject(RevoluteJoint2D(markerNumbers=[ends["coupler"][1],
                                                         mbs.AddMarker(MarkerBodyPosition(bodyNumber=body,
                                                                                          localPosition=[0, 0, 0]))]))
        else:
            mbs.AddObject(RevoluteJoint2D(markerNumbers=[ends["coupler"][1], ends["rocker"][1]]))
            D = mo.D[0]
            mbs.AddObject(RevoluteJoint2D(markerNumbers=[mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground,
                                                                                          localPosition=[D[0], D[1], 0.0])),
                                                         ends["rocker"][0]]))
        # Gauge sensors: the element(s) around the gauge position.
        self._gauge_sensors = {}
        for g in self.gauges:
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
            self._gauge_sensors[g.name] = (sensors, sec.depth_m, g.face)
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
        mbs.Assemble()

    def _rigid_link(self, mbs, link, mo, gravity):
        """A rigid link as one rigid body at its centre of mass (exact mass properties of the
        link, its end blocks and point masses). Returns its end position markers, the rigid marker
        at its start, and position sensors at its stations (for drawing)."""
        m, xc, Jc = link.rigid_body()
        lm = mo.link(link.name)
        pos, vel, _ = lm.point(np.array([xc]))
        node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[pos[0, 0, 0], pos[0, 0, 1], float(lm.angle[0])],
                                           initialVelocities=[vel[0, 0, 0], vel[0, 0, 1], float(lm.omega[0])]))
        body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=node, mass=m, inertia=Jc))
        if gravity is not None:
            mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=body)),
                                             loadVector=[gravity[0], gravity[1], 0.0]))

        def at(x, kind):
            return mbs.AddMarker(kind(bodyNumber=body, localPosition=[x - xc, 0.0, 0.0]))
        sensors = [mbs.AddSensor(SensorBody(bodyNumber=body, localPosition=[x - xc, 0.0, 0.0], storeInternal=True,
                                            writeToFile=False, outputVariableType=OVT.Position))
                   for x in link.stations]
        return (at(0.0, MarkerBodyPosition), at(link.length_m, MarkerBodyPosition)), at(0.0, MarkerBodyRigid), sensors

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
        try:
            exu.SolveDynamic(self.mbs, self.sims, updateInitialValues=True)
        except Exception as exc:   # exudyn raises its own SolverError after printing its diagnosis
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
