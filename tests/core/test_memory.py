"""The process's allocation for image-sized arrays (rigkit.core.memory): both settings
taken where the C library is glibc, and the arrays made after them intact."""

from __future__ import annotations

import platform

import numpy as np
import pytest

from rigkit.core.memory import tune_for_images


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_both_settings_are_taken_and_large_arrays_still_work() -> None:
    assert tune_for_images() == (True, True)
    for _ in range(3):  # freed and made again, as the pipeline does
        a = np.full((2048, 4096), 3.0, np.float64)  # 64 MiB, above the default threshold
        assert float(a.sum()) == 3.0 * a.size
        del a
