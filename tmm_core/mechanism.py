"""Mechanism descriptions (SI) and their instantaneous structures.

A four-bar is frozen, at each crank position, into Shin's *instantaneous structure*: the crank
is clamped at its ground pivot A (it carries the drive torque), the coupler is pinned to the
crank at B and to the rocker at C, and the rocker is pinned to the ground at D.

Member orientation (local x) and therefore the local +y ("top") face:
crank A->B, coupler B->C, rocker D->C (from its ground pivot).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .kinematics import FourBarGeometry, FourBarMotion, fourbar_motion
from .sections import Material, Section
from .structure import Joint, LoadCase, Member, Structure

FOURBAR_LINKS = ("crank", "coupler", "rocker")


@dataclass(frozen=True)
class Link:
    """A straight prismatic link: length [m], section, material, number of TMM segments."""

    name: str
    length_m: float
    section: Section
    material: Material
    n_segments: int = 8

    def member(self, start: str, end: str, **kw) -> Member:
        return Member.uniform(self.name, start, end, self.length_m, self.n_segments, self.section,
                              self.material, **kw)


@dataclass(frozen=True)
class FourBarMechanism:
    """Four-bar with flexible links. ``ground_m`` is the distance A-D [m]."""

    crank: Link
    coupler: Link
    rocker: Link
    ground_m: float
    pivot: tuple = (0.0, 0.0)
    ground_angle: float = 0.0
    branch: int = 1

    def __post_init__(self):
        for name, link in zip(FOURBAR_LINKS, (self.crank, self.coupler, self.rocker)):
            if link.name != name:
                raise InputError(f"four-bar: the {name} link must be named '{name}', got '{link.name}'")

    @property
    def geometry(self) -> FourBarGeometry:
        return FourBarGeometry(self.crank.length_m, self.coupler.length_m, self.rocker.length_m, self.ground_m,
                               self.pivot, self.ground_angle, self.branch)

    def links(self):
        return (self.crank, self.coupler, self.rocker)

    def structure(self) -> Structure:
        """Instantaneous structure: A clamped (crank welded), B and C revolutes, D pinned."""
        joints = (Joint("A", "clamped"), Joint("B"), Joint("C"), Joint("D", "pinned"))
        members = (self.crank.member("A", "B", start_connection="rigid"),
                   self.coupler.member("B", "C"),
                   self.rocker.member("D", "C"))
        return Structure(joints, members)

    def motion(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0) -> FourBarMotion:
        return fourbar_motion(self.geometry, crank_angle, crank_speed, crank_acceleration)

    def load_case(self, motion: FourBarMotion, node_loads=None, distributed_loads=None,
                  node_stiffness=None) -> LoadCase:
        """Load case at the positions of ``motion``; loads are ``{link: array}`` as in :class:`LoadCase`."""
        positions = {"A": motion.A, "B": motion.B, "C": motion.C, "D": motion.D}
        return LoadCase(positions, dict(node_loads or {}), dict(distributed_loads or {}),
                        dict(node_stiffness or {}))

    def gravity_loads(self, g=(0.0, -9.80665)):
        """Distributed self-weight ``{link: (n, 2)}`` [N/m] for gravity vector ``g`` [m/s^2]."""
        out = {}
        for link in self.links():
            w = link.material.density_kg_m3 * link.section.area_m2
            out[link.name] = np.broadcast_to(w * np.asarray(g, dtype=float), (link.n_segments, 2)).copy()
        return out
