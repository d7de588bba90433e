"""The face model travels once, parameters stream: in headless Chromium the
viewer's shader (read back through WebGL2 transform feedback) and its
JavaScript evaluator give the vertices the server's deform() gives, within
0.1 mm, on random FAP vectors, from the ``model`` message of
``/view?model=true``."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from realizer.face.deform import deform
from tests.face.test_gpu_model import TOLERANCE_M, random_vectors
from tests.service.browser import chromium_on_service
from tests.service.conftest import UNIT
from tests.service.test_end_to_end import real_assets, real_face, real_sessions

EVALUATE = """async (vectors) => {
  const fm = await import('/static/facemodel.js');
  const { decodeMsgpack } = await import('/static/realizer-client.js');
  const ws = new WebSocket(`ws://${location.host}/view?character=gpu&model=true&fap=false`);
  ws.binaryType = 'arraybuffer';
  const got = await new Promise((resolve, reject) => {
    const seen = {};
    ws.onmessage = (event) => {
      const m = decodeMsgpack(event.data);
      seen[m.type] = m;
      if (seen.mesh && seen.model) { ws.close(); resolve(seen); }
    };
    ws.onerror = () => reject(new Error('viewer socket failed'));
  });
  const neutral = new Float32Array(got.mesh.neutral.slice().buffer);
  const model = fm.parseModel(got.model, neutral);
  const canvas = document.createElement('canvas');
  const gl = canvas.getContext('webgl2');
  const gpu = gl ? fm.deformTransformFeedback(gl, model, vectors).map((a) => Array.from(a)) : null;
  const cpu = vectors.map((v) => Array.from(fm.deformCPU(model, v)));
  return { gpu, cpu, modelBytes: got.model.entries.length };
}"""


@pytest.mark.slow
def test_the_shader_and_the_javascript_deform_like_the_server() -> None:
    face = real_face()
    vectors = random_vectors(4, seed=11)
    with chromium_on_service(real_sessions(), real_assets()) as (service, browser):
        page = browser.new_page()
        page.set_default_timeout(60_000 * UNIT)
        page.goto(f"http://127.0.0.1:{service.port}/health")
        result: dict[str, Any] = page.evaluate(EVALUATE, [v.tolist() for v in vectors])
    assert result["gpu"] is not None, "headless Chromium gave no WebGL2 context"
    for vector, gpu, cpu in zip(vectors, result["gpu"], result["cpu"], strict=True):
        expected = deform(face, vector)
        moved = float(np.abs(expected - face.vertices).max())
        assert moved > 100 * TOLERANCE_M or not vector.any()
        gpu_error = np.abs(np.asarray(gpu).reshape(-1, 3) - expected).max()
        cpu_error = np.abs(np.asarray(cpu).reshape(-1, 3) - expected).max()
        assert gpu_error < TOLERANCE_M, f"shader off by {gpu_error * 1000:.4f} mm"
        assert cpu_error < TOLERANCE_M, f"JavaScript off by {cpu_error * 1000:.4f} mm"
