"""Rigid bodies of the exudyn model: a rigid link at its centre of mass, a light slider block,
and the rotation of a weld's marker frame. Pure builders on an exudyn ``MainSystem``; the engine
(:mod:`cosim.engines.exudyn`) owns the model and its state.

Owns: exudyn rigid-body builders. Boundaries: no engine state.
"""
from __future__ import annotations

import math

import numpy as np

import exudyn as exu
from exudyn.itemInterface import (LoadMassProportional, MarkerBodyMass, MarkerBodyPosition, NodeRigidBody2D,
                                  ObjectRigidBody2D, SensorBody)

OVT = exu.OutputVariableType
HUB_MASS_KG = 1e-3        # the hub only transmits the drive; its own inertia must not matter
HUB_INERTIA_KG_M2 = 1e-8


def rz(angle):
    """Rotation about z by ``angle`` [rad], 3x3 (a weld's marker frame offset)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rigid_link(mbs, link, mo, gravity):
    """A rigid link as one rigid body at its centre of mass (exact mass properties of the
    link, its end blocks and point masses). Returns its end position markers, the rigid marker
    at its start as (body, local position), and position sensors at its stations (for drawing)."""
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
    return (at(0.0, MarkerBodyPosition), at(link.length_m, MarkerBodyPosition)), (body, [-xc, 0.0, 0.0]), sensors

def light_block(mbs, position, velocity, angle, omega):
    """A light rigid block (slider) at ``position`` turned by ``angle``."""
    node = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[position[0], position[1], angle],
                                       initialVelocities=[velocity[0], velocity[1], omega]))
    return mbs.AddObject(ObjectRigidBody2D(nodeNumber=node, mass=HUB_MASS_KG, inertia=HUB_INERTIA_KG_M2))
