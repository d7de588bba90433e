"""deform's result is the caller's: a new C-contiguous (n, 3) float32 array.

The rig works on the coordinates as three rows (3, n) and converts at the
end, and the neutral frame is a copy of the face's vertices: writing into a
result (a stream's encoder, a renderer's buffer) must not change the rig's
state or the next frame.
"""

from __future__ import annotations

import numpy as np
import pytest

from realizer.face.default import load_default_face
from realizer.face.deform import rig_for
from realizer.face.testhead import build_test_head


@pytest.mark.parametrize("make", [load_default_face, build_test_head], ids=["default", "test"])
def test_every_result_is_a_new_c_contiguous_float32_array(make) -> None:  # type: ignore[no-untyped-def]
    face = make()
    rig = rig_for(face)
    talking = np.zeros(68)
    talking[[2, 3, 18, 47, 48]] = (300.0, 100.0, 200.0, 3000.0, -2000.0)
    for vector in (talking, np.zeros(68)):
        first = rig.deform(vector)
        posed, _ = rig.deform_posed(vector)
        for result in (first, posed):
            assert result.shape == (face.vertex_count, 3) and result.dtype == np.float32
            assert result.flags.c_contiguous and result.flags.writeable
        reference = first.copy()
        first += 1.0  # the caller's to change
        posed += 1.0
        np.testing.assert_array_equal(rig.deform(vector), reference)
    assert np.array_equal(rig.deform(np.zeros(68)), face.vertices)
    assert not np.array_equal(rig.deform(talking), face.vertices)
