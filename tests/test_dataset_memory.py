"""write_dataset holds a bounded number of frames: a job of 1,000 views at 320x240
peaks under 1 GB of resident memory, and no higher than its first 100 views plus a margin far
below what 900 more frames would take (900 x 320 x 240 x 11 bytes = 760 MB).

The job runs in a process of its own, which reports its peak resident size (ru_maxrss) after
the first 100 views (written by one call) and after all 1,000 (the other 900 by a second call,
as a shard would: first=100)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

_CHILD = textwrap.dedent("""
    import json, resource, sys
    import numpy as np, trimesh
    import softrast as sr

    views, directory = int(sys.argv[1]), sys.argv[2]
    tm = trimesh.creation.icosphere(subdivisions=4)
    scene = sr.Scene()
    scene.add(sr.Mesh(tm.vertices, tm.faces), instance_id=3)
    cams = []
    for pose in sr.orbit((0.0, 0.0, 0.0), 4.0, views, elevation=25.0):
        cam = sr.PerspectiveCamera(fov_y=40.0, width=320, height=240, near=0.1, far=20.0)
        cam.pose = pose
        cams.append(cam)
    outputs = ("color", "depth", "instance_id")
    a = sr.write_dataset(scene, cams[:100], directory, outputs=outputs, cameras_json=False)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    b = sr.write_dataset(scene, cams[100:], directory, outputs=outputs, first=100, cameras_json=False)
    print(json.dumps({"rendered": a.rendered + b.rendered, "base_kib": base,
                      "peak_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
""")


def _job(views: int, directory) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(views), str(directory)], check=True,
                         capture_output=True, text=True, timeout=600)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_thousand_views_in_bounded_memory(tmp_path):
    job = _job(1000, tmp_path)
    assert job["rendered"] == 1000
    assert len(os.listdir(tmp_path)) == 3 * 1000  # every file, no temporaries
    peak_mib, base_mib = job["peak_kib"] / 1024, job["base_kib"] / 1024
    assert peak_mib < 1024, f"1,000 views peaked at {peak_mib:.0f} MiB"
    # the 900 more frames add nothing held: at most allocator noise (the frames alone: 760 MB)
    assert peak_mib < base_mib + 128, f"100 views: {base_mib:.0f} MiB, 1,000 views: {peak_mib:.0f} MiB"
