"""example_pcl.frame_stream: the drop-oldest queue and the lost-frame count."""
import threading

from example_pcl.frame_stream import DropCounter, FrameQueue


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
