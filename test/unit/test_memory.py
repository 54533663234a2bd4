"""example_pcl.memory: glibc's allocator kept from handing cloud-sized blocks back to the kernel."""
import subprocess
import sys

FREED_MEMORY_PROBE = """
import queue, resource, sys, threading
from example_pcl.memory import keep_freed_memory
assert keep_freed_memory()
blocks = queue.Queue(maxsize=3)
def free_them():
    while blocks.get() is not None:
        pass
thread = threading.Thread(target=free_them)
thread.start()
for _ in range(5):
    blocks.put(bytes(bytearray(5 << 20)))
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(60):
    blocks.put(bytes(bytearray(5 << 20)))  # made here, freed in the other thread, as rospy's clouds are
blocks.put(None)
thread.join()
print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / (60 * (5 << 20) / 4096))
"""


def test_keep_freed_memory_reuses_cloud_sized_blocks():
    """With freed memory kept, 5 MB blocks made in one thread and freed in another fault in under 5% of their pages."""
    proc = subprocess.run([sys.executable, "-c", FREED_MEMORY_PROBE], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert float(proc.stdout) < 0.05
