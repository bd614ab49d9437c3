"""Materials and cross-sections (SI units).

Owns: materials and sections. Boundaries: no analysis.
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError, require_positive


@dataclass(frozen=True)
class Material:
    """Linear-elastic isotropic material.

    E_Pa : Young's modulus [Pa]; density_kg_m3 : mass density [kg/m^3];
    yield_strength_Pa, endurance_limit_Pa : for safety factors [Pa] (optional);
    poisson : Poisson's ratio (for the plane-strain variant of wide strips).
    """

    name: str
    E_Pa: float
    density_kg_m3: float = 0.0
    yield_strength_Pa: float | None = None
    endurance_limit_Pa: float | None = None
    poisson: float = 0.3

    def __post_init__(self):
        require_positive(f"material '{self.name}': E_Pa", self.E_Pa)
        if not (self.density_kg_m3 >= 0.0):
            raise InputError(f"material '{self.name}': density_kg_m3 must be >= 0, got {self.density_kg_m3!r}")
        for field in ("yield_strength_Pa", "endurance_limit_Pa"):
            v = getattr(self, field)
            if v is not None:
                require_positive(f"material '{self.name}': {field}", v)
        if not (-1.0 < self.poisson < 0.5):
            raise InputError(f"material '{self.name}': poisson must lie in (-1, 0.5), got {self.poisson!r}")


@dataclass(frozen=True)
class Section:
    """Cross-section for in-plane bending.

    area_m2 : A [m^2]; inertia_m4 : second moment about the out-of-plane axis [m^4];
    depth_m : in-plane depth h [m]; the surface fibres sit at y = +-h/2 (local +y = "top").
    """

    area_m2: float
    inertia_m4: float
    depth_m: float

    def __post_init__(self):
        require_positive("section area_m2", self.area_m2)
        require_positive("section inertia_m4", self.inertia_m4)
        require_positive("section depth_m", self.depth_m)

    @classmethod
    def rectangle(cls, width_m: float, depth_m: float) -> "Section":
        """Rectangular strip: ``width_m`` out of plane, ``depth_m`` in the bending plane."""
        require_positive("section width_m", width_m)
        require_positive("section depth_m", depth_m)
        return cls(width_m * depth_m, width_m * depth_m**3 / 12.0, depth_m)

    @property
    def section_modulus_m3(self) -> float:
        """Z = I / (h/2) [m^3]."""
        return self.inertia_m4 / (0.5 * self.depth_m)
