"""Coulomb friction (seed eqs. 2.8-2.11): contact model, exact simulation, time-optimal moves and their certificate."""

from .certificate import FrictionCertificate
from .contact import Contact, FrictionSystem, simulate_coulomb
from .profile import FrictionProfile
from .time_optimal import check_coulomb_force, plan_time_optimal_friction
from .zoh import plan_time_optimal_friction_zoh

__all__ = [
    "Contact",
    "FrictionCertificate",
    "FrictionProfile",
    "FrictionSystem",
    "check_coulomb_force",
    "plan_time_optimal_friction",
    "plan_time_optimal_friction_zoh",
    "simulate_coulomb",
]
