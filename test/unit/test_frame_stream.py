"""Unit tests of example_pcl.frame_stream: the drop-oldest queue and the lost-frame count (pcd_save),
the newest-frame slot and the stream's figures (can_tracker)."""
import threading

import numpy as np
import pytest

from example_pcl.frame_stream import DropCounter, FrameQueue, NewestFrame, StreamStats, percentiles


def test_drop_counter_counts_sequence_gaps_per_publisher():
    """Gaps in header.seq count as drops, per publisher; a sequence going back is a restart, not a drop."""
    drops = DropCounter()
    gaps = [drops.observe(s, "/a") for s in (1, 2, 5, 6)]
    assert gaps == [0, 0, 2, 0]
    drops.observe(100, "/b")
    drops.observe(101, "/b")
    assert drops.seq_gaps == 2
    assert drops.observe(1, "/a") == 0 and drops.restarts == 1
    drops.discarded(3)
    assert drops.dropped == 5 and drops.received == 7
    assert "sequence gaps 2" in drops.summary() and "queue discards 3" in drops.summary()


def test_frame_queue_discards_the_oldest_when_full():
    """put never blocks: with the queue full the oldest item goes and put reports one discard."""
    queue = FrameQueue(2)
    assert [queue.put(i) for i in range(4)] == [0, 0, 1, 1]
    assert queue.get(0) == 2 and queue.get(0) == 3 and queue.get(0) is None
    queue.put(9)
    assert queue.close() == 1 and queue.get() is None  # closed: getters wake up


def test_frame_queue_get_waits_for_a_put():
    """get blocks until another thread puts an item."""
    queue = FrameQueue(1)
    threading.Timer(0.05, queue.put, args=("x",)).start()
    assert queue.get(timeout=5) == "x"


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


def test_stream_stats_stages():
    """Each stage's p50 and p90 over the frames that ran it, in the order first seen; old ones leave."""
    stats = StreamStats(window=1.0)
    for k in range(10):
        stats.done(k / 10, latency=0.02, compute=0.005,
                   stages={"convert": 0.001 * (k + 1), **({"search": 0.02} if k % 5 == 0 else {})})
    s = stats.summary(0.95)
    assert list(s["stages"]) == ["convert", "search"]
    assert s["stages"]["convert"] == (pytest.approx(0.0055), pytest.approx(0.0091), 10)
    assert s["stages"]["search"] == (pytest.approx(0.02), pytest.approx(0.02), 2)
    stats.done(2.5, latency=0.02, compute=0.005, stages={"convert": 0.5})
    assert stats.summary(2.5)["stages"] == {"convert": (0.5, 0.5, 1)}


def test_percentiles_of_nothing_are_nan():
    assert all(np.isnan(v) for v in percentiles([]).values())
    assert percentiles([1.0, 2.0, 3.0], (50,)) == {50: 2.0}


def test_stream_stats_rejects_a_window_of_zero():
    with pytest.raises(ValueError):
        StreamStats(window=0)
