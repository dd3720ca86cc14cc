"""The array types of the numerics: numpy arrays of float64 (SI values, matrices), complex128
(phasors, impedances), int64 (counts, indexes) and bool (masks); and the noise model of a design."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from numpy.typing import ArrayLike

FloatArray = npt.NDArray[np.float64]
ComplexArray = npt.NDArray[np.complex128]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: per-revolution noise (k, 4) of x, y (m), fx, fy (N) at orbit ratios (k,)
NoiseAt = Callable[[ArrayLike], FloatArray]
