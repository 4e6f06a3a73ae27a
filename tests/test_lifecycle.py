"""Process and thread lifecycle: fork, thread creation failure, exit.

Everything that could hang runs in a child process under a generous timeout (a guard, not a
measurement): a hang fails the test and the child's whole process group is killed.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap

import pytest

import softrast as sr
from softrast import _core

TIMEOUT = 60.0  # seconds; each child below takes well under one (a few under ASan)

# Shared by the child scripts: a scene without trimesh (a child starts in ~0.2 s without it),
# digests of renders, the process's thread count.
PRELUDE = r'''
import gc, hashlib, os, re, sys, threading, warnings
import numpy as np
import softrast as sr
from softrast import _core

# Python 3.12+ warns on fork() in a process with threads; forking with threads is the point here.
warnings.filterwarnings("ignore", message=r".*fork\(\) may lead to deadlocks", category=DeprecationWarning)

def sphere(rings):
    """A UV sphere of 4 * rings**2 triangles, outward faces."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * rings, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(rings), np.arange(2 * rings), indexing="ij")
    a = i * 2 * rings + j
    b = i * 2 * rings + (j + 1) % (2 * rings)
    c, d = a + 2 * rings, b + 2 * rings
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3),
                            np.stack([b, c, d], -1).reshape(-1, 3)])
    return sr.Mesh(v, faces)

def scene_and_camera(rings=24):
    scene = sr.Scene()
    scene.add(sphere(rings), color=(0.8, 0.5, 0.3))
    cam = sr.PerspectiveCamera(fov_y=40.0).look_at(eye=(0.4, 0.7, 3.0), target=(0.0, 0.0, 0.0))
    return scene, cam

OUTPUTS = ("color", "depth", "normal", "triangle_id")

def digest(renderer, scene, cam):
    frame = renderer.render(scene, cam, outputs=OUTPUTS)
    h = hashlib.sha256()
    for name in OUTPUTS:
        h.update(getattr(frame, name).tobytes())
    return h.hexdigest()

def tasks():
    return len(os.listdir("/proc/self/task"))

def wait_for_tasks(n, seconds=10.0):
    """A joined thread leaves /proc/self/task a moment after join() returns."""
    import time
    deadline = time.monotonic() + seconds
    while tasks() != n and time.monotonic() < deadline:
        time.sleep(0.005)
    return tasks()

def wait_child(pid):
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
'''


def start_child(tmp_path, body: str, *args: str) -> subprocess.Popen:
    """Starts PRELUDE + body as a script file (spawn and forkserver re-import it) in a new
    process group."""
    script = tmp_path / f"child{len(list(tmp_path.glob('child*.py')))}.py"  # one per child
    script.write_text(PRELUDE + textwrap.dedent(body))
    return subprocess.Popen([sys.executable, str(script), *args], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def finish_child(proc: subprocess.Popen) -> subprocess.CompletedProcess:
    """Waits for a child; on a hang, kills its group (forked grandchildren too) and fails."""
    try:
        out, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"child hung (killed after {TIMEOUT:.0f} s)\nstdout:\n{out}\nstderr:\n{err}")
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def run_child(tmp_path, body: str, *args: str) -> subprocess.CompletedProcess:
    return finish_child(start_child(tmp_path, body, *args))


def assert_clean(proc: subprocess.CompletedProcess, expected_stdout: str) -> None:
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.split() == expected_stdout.split(), proc.stdout + proc.stderr


# ------------------------------------------------------------------------------------------------
# 1. fork


def test_fork_child_destroys_inherited_renderer(tmp_path):
    # The child's pool threads do not exist: destroying the renderer must not join them (it hung).
    proc = run_child(tmp_path, """
        scene, cam = scene_and_camera()
        used = sr.Renderer(64, 48, threads=3)
        digest(used, scene, cam)                 # its workers have run
        unused = sr.Renderer(64, 48, threads=2)  # never rendered
        for name in ("used", "unused"):
            pid = os.fork()
            if pid == 0:
                del globals()[name]
                gc.collect()
                os._exit(0)
            print(name, wait_child(pid))
        # The parent's own renderers still join their 2 + 1 workers. (Counted from here: NumPy's
        # OpenBLAS stops its threads before a fork, so the count at start-up is no baseline.)
        before = tasks()
        del used, unused
        print("threads back", wait_for_tasks(before - 3) == before - 3)
    """)
    assert_clean(proc, "used 0 unused 0 threads back True")


def test_fork_child_renders_the_parents_bits(tmp_path):
    # The inherited renderer starts new workers in the child (and again in a grandchild); every
    # frame equals the parent's, as does one from a renderer created in the child.
    proc = run_child(tmp_path, """
        scene, cam = scene_and_camera()
        renderer = sr.Renderer(96, 64, threads=3)
        want = digest(renderer, scene, cam)
        pid = os.fork()
        if pid == 0:
            got = [digest(renderer, scene, cam) for _ in range(3)]
            got.append(digest(sr.Renderer(96, 64, threads=2), scene, cam))
            grandchild = os.fork()
            if grandchild == 0:
                os._exit(0 if digest(renderer, scene, cam) == want else 1)
            ok = got == [want] * 4 and wait_child(grandchild) == 0
            os._exit(0 if ok else 1)
        print("child", wait_child(pid))
        print("parent", digest(renderer, scene, cam) == want)
    """)
    assert_clean(proc, "child 0 parent True")


def test_fork_child_exits_normally_holding_renderers(tmp_path):
    # Normal exit: the interpreter finalizes and destroys the inherited renderers (hung before).
    proc = run_child(tmp_path, """
        scene, cam = scene_and_camera()
        renderers = [sr.Renderer(64, 48, threads=t) for t in (0, 1, 2, 4)]
        want = [digest(r, scene, cam) for r in renderers]
        pid = os.fork()
        if pid == 0:
            ok = [digest(r, scene, cam) for r in renderers[::2]] == want[::2]
            sys.exit(0 if ok else 1)  # renderers[1::2] never rendered in the child
        print("child", wait_child(pid))
    """)
    assert_clean(proc, "child 0")


MULTIPROCESSING = """
    import multiprocessing
    W, H = 80, 60
    SCENE, CAM = scene_and_camera()
    # Created when the module is imported: inherited by "fork" workers and, with "forkserver",
    # by the workers forked from the server (which imports this module too); "spawn" workers
    # create their own.
    RENDERER = sr.Renderer(W, H, threads=2)
    WANT = digest(RENDERER, SCENE, CAM)

    def work(k):
        return digest(RENDERER, SCENE, CAM)

    if __name__ == "__main__":
        ctx = multiprocessing.get_context(sys.argv[1])
        pool = ctx.Pool(2)
        got = pool.map(work, range(8))
        pool.close()
        pool.join()  # workers exit on their own; a hang here is a failure
        print(sum(g == WANT for g in got))
"""


@pytest.mark.parametrize("method", ["fork", "spawn", "forkserver"])
def test_multiprocessing_pool_renders_in_workers(tmp_path, method):
    assert_clean(run_child(tmp_path, MULTIPROCESSING, method), "8")


def test_process_pool_initializer_replaces_inherited_renderer(tmp_path):
    # A dataset job's usual shape: a global renderer, replaced in each worker by an initializer.
    # Replacing it destroys the inherited one in the worker (hung before).
    proc = run_child(tmp_path, """
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        W, H = 80, 60
        SCENE, CAM = scene_and_camera()
        RENDERER = sr.Renderer(W, H, threads=2)
        WANT = digest(RENDERER, SCENE, CAM)

        def init(threads):
            global RENDERER
            RENDERER = sr.Renderer(W, H, threads=threads)

        def work(k):
            return digest(RENDERER, SCENE, CAM)

        if __name__ == "__main__":
            for threads in (2, 1):
                with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"),
                                         initializer=init, initargs=(threads,)) as pool:
                    got = list(pool.map(work, range(6)))
                print(sum(g == WANT for g in got))
    """)
    assert_clean(proc, "6 6")


def test_fork_while_another_thread_renders(tmp_path):
    # Another thread renders big frames with the same renderer in a loop; each fork happens while
    # it is inside render() (it sets the event just before the call; the main thread gets the GIL
    # back only once the render has released it). fork() waits for that render to end, so the
    # child finds the renderer unlocked: it renders the right bits and exits normally (before,
    # the lock stayed held in the child and its first render hung).
    proc = run_child(tmp_path, """
        big, cam = scene_and_camera(rings=160)     # 102,400 triangles
        small, _ = scene_and_camera()
        renderer = sr.Renderer(1024, 1024, threads=2)
        want = digest(renderer, small, cam)
        stop, rendering = threading.Event(), threading.Event()

        def loop():
            while not stop.is_set():
                rendering.set()
                renderer.render(big, cam, outputs=("color", "depth", "normal"))

        thread = threading.Thread(target=loop, daemon=True)
        thread.start()
        for _ in range(3):
            rendering.clear()
            rendering.wait()
            pid = os.fork()
            if pid == 0:
                sys.exit(0 if digest(renderer, small, cam) == want else 1)
            print("child", wait_child(pid))
        stop.set()
        thread.join()
        print("parent", digest(renderer, small, cam) == want)
    """)
    assert_clean(proc, "child 0 child 0 child 0 parent True")


# ------------------------------------------------------------------------------------------------
# 2. thread creation


def test_threads_is_capped_at_max_threads():
    assert sr.MAX_THREADS == _core.MAX_THREADS == 256
    for bad in (sr.MAX_THREADS + 1, 10**6):
        with pytest.raises(ValueError, match=r"threads must be .*256.*got"):
            sr.Renderer(8, 8, threads=bad)
    for bad in (-1, 257, 2**31 - 1):  # the core checks too
        with pytest.raises(ValueError, match=r"threads must be in \[0, 256\]"):
            _core.Renderer(8, 8, bad)


def test_max_threads_renders_the_same_bits(tmp_path):
    proc = run_child(tmp_path, """
        scene, cam = scene_and_camera()
        base = tasks()
        want = digest(sr.Renderer(300, 200, threads=1), scene, cam)
        r = sr.Renderer(300, 200, threads=sr.MAX_THREADS)
        print(r.threads, tasks() - base, digest(r, scene, cam) == want)
        del r
        print(wait_for_tasks(base) == base)
    """)
    assert_clean(proc, "256 255 True True")


def test_thread_start_failure_raises_and_leaves_no_thread(tmp_path):
    # Fault injection (works under ASan too): the k-th worker fails to start. The constructor
    # raises RuntimeError naming `threads` after joining the k - 1 workers it started (it hung).
    # In a forked child the first render starts the workers again: the same error there, and the
    # next render retries.
    proc = run_child(tmp_path, """
        scene, cam = scene_and_camera()
        base = tasks()
        for k in (1, 2, 5, 7):
            _core._fail_thread_start(k)
            try:
                sr.Renderer(64, 48, threads=8)
                print("no error")
            except RuntimeError as e:
                assert re.search(rf"threads=8: could not start worker thread {k} \\(", str(e)), e
                print("RuntimeError", wait_for_tasks(base) == base)
        _core._fail_thread_start(0)
        want = digest(sr.Renderer(64, 48, threads=1), scene, cam)
        renderer = sr.Renderer(64, 48, threads=4)
        print("after", tasks() - base, digest(renderer, scene, cam) == want)
        pid = os.fork()
        if pid == 0:
            base = tasks()
            _core._fail_thread_start(2)
            try:
                digest(renderer, scene, cam)
                os._exit(1)
            except RuntimeError as e:
                if "threads=4: could not start worker thread 2" not in str(e):
                    os._exit(2)
            if wait_for_tasks(base) != base:
                os._exit(3)
            if digest(renderer, scene, cam) != want or tasks() != base + 3:
                os._exit(4)
            os._exit(0)
        print("child", wait_child(pid))
    """)
    assert_clean(proc, "RuntimeError True " * 4 + "after 3 True child 0")


def test_thread_start_failure_under_address_space_limit(tmp_path):
    # The real thing: an address-space cap (ulimit -v) set at run time, a little above what the
    # process maps already, so that the workers' stacks (8 MiB each by default) cannot all be
    # mapped. Set after start-up it works under ASan too (its shadow is mapped by then).
    proc = run_child(tmp_path, """
        import resource
        scene, cam = scene_and_camera()
        want = digest(sr.Renderer(64, 48, threads=1), scene, cam)
        base = tasks()
        stack = resource.getrlimit(resource.RLIMIT_STACK)[0]
        stack = 8 << 20 if stack == resource.RLIM_INFINITY else stack
        vm = next(int(l.split()[1]) << 10 for l in open("/proc/self/status") if l.startswith("VmSize:"))
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        resource.setrlimit(resource.RLIMIT_AS, (vm + min(64 << 20, stack * 256 // 4), hard))
        try:
            sr.Renderer(64, 48, threads=256)
            print("no error")
        except RuntimeError as e:
            print("RuntimeError", "threads=256: could not start worker thread" in str(e))
        print(wait_for_tasks(base) == base)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
        print(digest(sr.Renderer(64, 48, threads=4), scene, cam) == want)
    """)
    assert_clean(proc, "RuntimeError True True True")


# ------------------------------------------------------------------------------------------------
# 3. exit

EXIT_WHILE_RENDERING = """
    import time
    scene, cam = scene_and_camera(rings=64)
    renderer = sr.Renderer(512, 512, threads=2)
    rendered = threading.Event()

    def loop():
        while True:
            renderer.render(scene, cam, outputs=("color", "depth", "normal"))
            rendered.set()

    threading.Thread(target=loop, daemon=True).start()
    rendered.wait()

    class AtFinalization:
        # Destroyed once the interpreter is finalizing, with the modules: this sleep then
        # releases the GIL long enough for the daemon thread's render to end, at which point it
        # asks for the GIL back. Reports how many threads parked instead (the path under test).
        def __del__(self, sleep=time.sleep, write=os.write, parked=_core._parked_threads):
            sleep(0.1)
            write(1, b"parked %d\\n" % parked())

    # Not a global of __main__: the daemon thread's frame keeps that namespace alive to the end.
    holder = type(sys)("holder")
    holder.keeper = AtFinalization()
    sys.modules["holder"] = holder
    del holder
"""


def test_daemon_thread_rendering_while_the_interpreter_exits(tmp_path):
    # It aborted the process with "terminate called without an active exception" (a known
    # pybind11 problem, github.com/pybind/pybind11/issues/2215): now the thread parks, touching
    # nothing of Python's, and the process exits 0.
    runs = 10
    parked = 0
    children = [start_child(tmp_path, EXIT_WHILE_RENDERING) for _ in range(runs)]
    try:
        for child in children:
            proc = finish_child(child)
            assert proc.returncode == 0, proc.stdout + proc.stderr
            assert "terminate" not in proc.stderr, proc.stderr
            match = re.fullmatch(r"parked (\d+)\n", proc.stdout)
            assert match, proc.stdout + proc.stderr
            parked += int(match.group(1))
    finally:
        for child in children:
            if child.poll() is None:  # after a failure: leave no child behind
                os.killpg(child.pid, signal.SIGKILL)
                child.communicate()
    # The overlap was real: the daemon thread ended a render during finalization in most runs
    # (the others caught it between renders, where Python ends it without our help).
    assert parked >= runs // 2, parked
