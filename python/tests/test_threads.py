"""Locators from several threads at once (the GIL is released while they work), and Ctrl-C
during long calls."""

from __future__ import annotations

import os
import signal
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from conftest import kuhn_grid

import tetloc


def test_two_locators_at_once_from_two_threads(grid_mesh, data_dir):
    torus = tetloc.read(data_dir / "torus_s.vtu")
    rng = np.random.default_rng(5)
    jobs = [
        (tetloc.Locator(grid_mesh, backend="cpu"), rng.uniform(-1, 7, (200_000, 3)).astype(np.float32), "f"),
        (tetloc.Locator(torus, backend="cpu"), rng.uniform(-1.5, 1.5, (200_000, 3)).astype(np.float32), "f"),
    ]
    want = [(loc.locate(p), loc.sample(p, f)) for loc, p, f in jobs]
    barrier = threading.Barrier(2)

    def work(i):
        loc, p, f = jobs[i]
        barrier.wait()
        return [(loc.locate(p), loc.locate_and_sample(p, f)[1]) for _ in range(5)]

    with ThreadPoolExecutor(2) as pool:
        results = list(pool.map(work, [0, 1]))
    for (ids, vals), runs in zip(want, results):
        for got_ids, got_vals in runs:
            np.testing.assert_array_equal(got_ids, ids)
            np.testing.assert_array_equal(got_vals, vals)


def test_one_locator_shared_by_threads(grid_mesh):
    loc = tetloc.Locator(grid_mesh, backend="cpu")
    pts = np.random.default_rng(6).uniform(-1, 7, (50_000, 3))
    want = loc.locate(pts)
    with ThreadPoolExecutor(4) as pool:
        for got in pool.map(lambda _: loc.locate(pts), range(8)):
            np.testing.assert_array_equal(got, want)


def interrupted(call, after: float = 0.2) -> bool:
    """Sends SIGINT (Ctrl-C) `after` seconds into `call`: True when `call` raised
    KeyboardInterrupt, False when it had returned first."""
    # A process that a shell started in the background inherits SIGINT ignored, and Python
    # then installs no KeyboardInterrupt handler: install it here, as an interactive run has it.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        timer = threading.Timer(after, os.kill, (os.getpid(), signal.SIGINT))
        timer.start()
        try:
            call()
        except KeyboardInterrupt:
            return True
        try:
            time.sleep(10)  # the signal lands here when `call` was quicker
        except KeyboardInterrupt:
            return False
        raise AssertionError("no SIGINT arrived")
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.fixture(scope="module")
def big_mesh():
    """About 1.3M tets: builds take long enough to be interrupted on any machine."""
    return tetloc.Mesh(*kuhn_grid(60))


def test_ctrl_c_interrupts_a_long_locate(big_mesh):
    loc = tetloc.Locator(big_mesh, backend="cpu")
    pts = np.random.default_rng(7).uniform(0, 60, (30_000_000, 3)).astype(np.float32)
    assert interrupted(lambda: loc.locate(pts))
    assert loc.locate(pts[:1000]).min() >= 0  # still usable afterwards


def test_ctrl_c_interrupts_a_build(big_mesh):
    assert interrupted(lambda: tetloc.Locator(big_mesh, backend="cpu"), after=0.05)
