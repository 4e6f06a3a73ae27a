"""Worker functions for tests/test_pickle_processes.py: importable by spawn and forkserver
children (a test module's own functions are not, under every runner)."""
from __future__ import annotations

import pickle


def render_bytes(payload: bytes) -> dict[str, bytes]:
    """Unpickles (renderer, scene, camera, outputs), renders, returns each output's bytes."""
    renderer, scene, camera, outputs = pickle.loads(payload)
    frame = renderer.render(scene, camera, outputs=outputs)
    return {name: getattr(frame, name).tobytes() for name in outputs}
