"""International Standard Atmosphere, troposphere (below 11 km).

Pressure altitude relative to a reference pressure taken at the reference
point, so ``height_ref_m(p_ref, p_ref) == 0``. Pure functions, SI units.
"""

from __future__ import annotations

from .constants import G0_MPS2

T0_K = 288.15  # ISA sea-level temperature
L_KPM = 0.0065  # temperature lapse rate, K/m
R_AIR = 287.05287  # specific gas constant of dry air, J/(kg K)
P0_PA = 101325.0
_EXP = R_AIR * L_KPM / G0_MPS2  # ~0.190263


def height_from_pressure_m(pressure_pa: float, p_ref_pa: float, t_ref_k: float = T0_K) -> float:
    """Height above the point where the pressure is ``p_ref_pa`` (ISA lapse)."""
    if not (pressure_pa > 0.0 and p_ref_pa > 0.0):
        raise ValueError("pressures must be positive")
    return (t_ref_k / L_KPM) * (1.0 - (pressure_pa / p_ref_pa) ** _EXP)


def heights_from_pressures_m(pressure_pa, p_ref_pa: float, t_ref_k: float = T0_K):
    """:func:`height_from_pressure_m` over a numpy array of positive pressures."""
    return (t_ref_k / L_KPM) * (1.0 - (pressure_pa / p_ref_pa) ** _EXP)


def pressure_at_height_pa(height_m: float, p_ref_pa: float, t_ref_k: float = T0_K) -> float:
    """Inverse of :func:`height_from_pressure_m`."""
    return p_ref_pa * (1.0 - L_KPM * height_m / t_ref_k) ** (1.0 / _EXP)


def isa_pressure_at_msl_alt_pa(alt_msl_m: float) -> float:
    """Standard-day static pressure at an altitude above mean sea level."""
    return pressure_at_height_pa(alt_msl_m, P0_PA)

