"""The compiled kernels (``pinstab._compiled``, sources in ``cpp/``): the core evaluation of the standard rows (whose
row functions pinstab's constraint classes call too, as the solvers call its residual and pivot test, the grasp hold
its least squares and cone test, a joint spring its force, an external force its J^T w, a target trajectory its
evaluation, the general servo solve its part up to the controls and the native path its residual: a rule lives in C++
once), Pinocchio's constrained dynamics, the banded solve, the servo solve and the grasp evaluation in C++
(:mod:`pinstab.paths`), the explicit step loop over them (:mod:`pinstab.integration.compiled`), the explicit schemes'
steps that the Python loops take too, their stages evaluated by a Python callable (:mod:`pinstab.integration.schemes`),
the error-controlled loop of an embedded pair and its control's rules (:mod:`pinstab.integration.adaptive`), a
fingertip contact's point rows (:mod:`pinstab.constraints.grasp_contacts`), the drift and energy series of a run of
compiled rows (:mod:`pinstab.series`), the checked cone solve (:mod:`pinstab.solvers.ncp`), the plane contacts' rows
(:mod:`pinstab.solvers.contact_modes`), the contact features of collision-shape pairs (:mod:`pinstab.contact.geometry`)
and the numeric part of the time-stepping contacts' step (:mod:`pinstab.integration.contact_stepping`).

The extension is built by ``pip install`` against the ``pin`` release pinstab pins; it links against that
release's libraries, so another ``pin`` installed afterwards cannot load it: the import error says what to do.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    from ._compiled import (
        SPRING_COINCIDENT_LENGTH,
        AdaptivePair,
        BandedKernel,
        CompiledActuators,
        CompiledTarget,
        ConeSolver,
        ConeStepper,
        CoreCorrection,
        CoreKernel,
        CoreProjection,
        GeometryFeatures,
        Kernel,
        NativeKernel,
        NewtonFailure,
        RowBlock,
        RungeKutta,
        SchemeStep,
        Segment,
        ServoKernel,
        ServoParts,
        baumgarte_velocity_gains,
        block_drift,
        block_jacobian,
        block_rate,
        block_residual,
        closest_solution,
        closure_series,
        cones_hold,
        contact_holds,
        contact_margins,
        contact_point_drift,
        contact_point_jacobian,
        contact_point_residual,
        contact_point_world_jacobian,
        contact_point_world_rate,
        controls_within,
        correct,
        delassus_pseudo_inverse,
        direct_solve,
        hermite_coefficients,
        hermite_state,
        hold_torques,
        inertial_matrices,
        joint_limit_gap,
        joint_limit_gaps,
        joint_limit_rate,
        joint_limit_rates,
        joint_spring_force,
        kkt_cost_split,
        least_norm,
        native_residual,
        ncp_residual,
        plane_contact_rows,
        primal_residual,
        project_positions,
        servo_parts,
        servo_realizability,
        spring_damper_terms,
        stabilization_term,
        tilted_gravity,
        weighted_correction,
        wrench_force,
    )
except ImportError as error:  # pragma: no cover - a broken install
    try:
        pin_release = version("pin")
    except PackageNotFoundError:
        pin_release = "none"
    raise ImportError(
        f"pinstab's compiled step loop (pinstab._compiled) cannot be loaded ({error}); it is built by pip install "
        f"against the pin release in pinstab's requirements (installed now: pin {pin_release}). Reinstall pinstab "
        "(pip install -e . in its checkout, or pip install --force-reinstall pinstab)"
    ) from error

__all__ = [
    "AdaptivePair",
    "BandedKernel",
    "CompiledActuators",
    "CompiledTarget",
    "ConeSolver",
    "ConeStepper",
    "CoreCorrection",
    "CoreKernel",
    "CoreProjection",
    "GeometryFeatures",
    "Kernel",
    "NativeKernel",
    "NewtonFailure",
    "RowBlock",
    "RungeKutta",
    "SchemeStep",
    "Segment",
    "ServoKernel",
    "ServoParts",
    "SPRING_COINCIDENT_LENGTH",
    "stabilization_term",
    "baumgarte_velocity_gains",
    "block_drift",
    "block_jacobian",
    "block_rate",
    "block_residual",
    "closest_solution",
    "closure_series",
    "cones_hold",
    "contact_holds",
    "contact_margins",
    "contact_point_drift",
    "contact_point_jacobian",
    "contact_point_residual",
    "contact_point_world_jacobian",
    "contact_point_world_rate",
    "controls_within",
    "correct",
    "delassus_pseudo_inverse",
    "direct_solve",
    "hermite_coefficients",
    "hermite_state",
    "hold_torques",
    "inertial_matrices",
    "joint_limit_gap",
    "joint_limit_gaps",
    "joint_limit_rate",
    "joint_limit_rates",
    "joint_spring_force",
    "kkt_cost_split",
    "least_norm",
    "native_residual",
    "ncp_residual",
    "plane_contact_rows",
    "primal_residual",
    "project_positions",
    "servo_parts",
    "servo_realizability",
    "spring_damper_terms",
    "tilted_gravity",
    "weighted_correction",
    "wrench_force",
]
