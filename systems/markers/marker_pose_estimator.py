"""MarkerPoseEstimator: the panel pose X_CP from a camera's colour image (Annusewicz-Mistal et al.).

The mathematics is MarkerPoseSolver (systems/markers/marker_pose_estimator_math.py). Outputs
are computed on demand and cached per image, so a camera is rendered only when a consumer
evaluates them (PanelOperation does so only while the arm stands still)."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from pydrake.systems.sensors import ImageRgba8U

from guidedarm.systems.config_checks import CheckInstance
from guidedarm.systems.markers.marker_pose_estimator_math import (
    MarkerPoseEstimate,
    MarkerPoseSolver,
)


class MarkerPoseEstimator(LeafSystem):
    """Colour image in; panel pose in the camera frame out.

    Input port: `color_image` (ImageRgba8U, the camera's size).
    Output ports: `X_CP` (RigidTransform, m; identity when invalid), `ids` (list[int] of the
    known markers used), `reprojection_error_px` (1-vector, RMS px, -1 when no marker),
    `valid` (1-vector, 1.0 or 0.0: a reprojection error within bounds and a camera model
    that fits the image), `pose_std` (6-vector: the standard deviations of p_CP along C's
    x y z in mm, then of the rotation about C's x y z in deg; infinite without a pose),
    `estimate` (the whole MarkerPoseEstimate, with the model check).
    """

    def __init__(self, solver: MarkerPoseSolver) -> None:
        super().__init__()
        CheckInstance("solver", solver, MarkerPoseSolver)
        self._solver = solver
        self._image = self.DeclareAbstractInputPort(
            "color_image", AbstractValue.Make(ImageRgba8U())
        )
        # Output ports are cached: the others read `estimate`, so one image is analysed once.
        depends = {self._image.ticket()}
        self._estimate = self.DeclareAbstractOutputPort(
            "estimate",
            lambda: AbstractValue.Make(MarkerPoseEstimate(None, [], -1.0, False)),
            self._CalcEstimate,
            prerequisites_of_calc=depends,
        )
        self.DeclareAbstractOutputPort(
            "X_CP",
            lambda: AbstractValue.Make(RigidTransform()),
            self.CalcX_CP,
            prerequisites_of_calc=depends,
        )
        self.DeclareAbstractOutputPort(
            "ids", lambda: AbstractValue.Make([0]), self.CalcIds, prerequisites_of_calc=depends
        )
        self.DeclareVectorOutputPort(
            "reprojection_error_px",
            1,
            self.CalcReprojectionError,
            prerequisites_of_calc=depends,
        )
        self.DeclareVectorOutputPort("valid", 1, self.CalcValid, prerequisites_of_calc=depends)
        self.DeclareVectorOutputPort("pose_std", 6, self.CalcPoseStd, prerequisites_of_calc=depends)

    @property
    def solver(self) -> MarkerPoseSolver:
        """The solver (camera intrinsics and panel) this estimator runs."""
        return self._solver

    def _CalcEstimate(self, context: Context, value: AbstractValue) -> None:
        image = self._image.Eval(context)
        value.set_value(self._solver.estimate(np.asarray(image.data)))

    def _Get(self, context: Context) -> MarkerPoseEstimate:
        return self._estimate.Eval(context)

    def CalcX_CP(self, context: Context, value: AbstractValue) -> None:
        X_CP = self._Get(context).X_CP
        value.set_value(X_CP if X_CP is not None else RigidTransform())

    def CalcIds(self, context: Context, value: AbstractValue) -> None:
        value.set_value(list(self._Get(context).ids))

    def CalcReprojectionError(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._Get(context).reprojection_error_px)

    def CalcValid(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, 1.0 if self._Get(context).valid else 0.0)

    def CalcPoseStd(self, context: Context, output: BasicVector) -> None:
        estimate = self._Get(context)
        std = [*estimate.std_mm, *estimate.std_deg]
        output.SetFromVector(std if len(std) == 6 else np.full(6, np.inf))
