"""Unit tests of example_pcl.frame_stream: the newest-frame slot and the stream's figures."""
import threading

import numpy as np
import pytest

from example_pcl.frame_stream import NewestFrame, StreamStats, percentiles


def test_newest_frame_replaces_and_counts_skipped():
    """A frame not taken is replaced by the next one and counted as skipped; take returns the newest."""
    slot = NewestFrame()
    assert slot.put(1) is False and slot.put(2) is True and slot.put(3) is True
    assert slot.take() == 3 and slot.skipped == 2
    assert slot.take(timeout=0.01) is None


def test_newest_frame_wakes_a_waiting_worker_and_closes():
    """A worker waiting in take gets the item put from another thread; close ends every take."""
    slot, got = NewestFrame(), []
    worker = threading.Thread(target=lambda: got.extend([slot.take(), slot.take()]))
    worker.start()
    slot.put("frame")
    while slot._item is not None:  # the worker took it
        pass
    slot.close()
    worker.join(timeout=5)
    assert got == ["frame", None] and slot.closed and slot.take() is None


def test_stream_stats_rates_and_percentiles():
    """Rates over the window, latency percentiles, compute mean; old frames leave the window."""
    stats = StreamStats(window=2.0)
    for k in range(60):
        t = k / 30
        stats.arrived(t)
        if k % 2 == 0:
            stats.done(t + 0.01, latency=0.01 * (1 + k % 10), compute=0.004)
    stats.refused()
    s = stats.summary(2.0)
    assert s["input_rate"] == pytest.approx(30.0, abs=1) and s["processed_rate"] == pytest.approx(15.0, abs=1)
    assert s["received"] == 60 and s["processed"] == 30 and s["dropped"] == 1
    assert s["compute_mean"] == pytest.approx(0.004) and 0.01 <= s["latency_p50"] <= s["latency_p99"] <= 0.1
    later = stats.summary(10.0)
    assert later["input_rate"] == 0 and np.isnan(later["latency_p50"]) and later["since_last_input"] == pytest.approx(
        10.0 - 59 / 30)


def test_percentiles_of_nothing_are_nan():
    assert all(np.isnan(v) for v in percentiles([]).values())
    assert percentiles([1.0, 2.0, 3.0], (50,)) == {50: 2.0}


def test_stream_stats_rejects_a_window_of_zero():
    with pytest.raises(ValueError):
        StreamStats(window=0)
