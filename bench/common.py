"""Helpers shared by the benchmarks: timing, the machine line, tables, writing figures into docs/benchmarks.md."""
import os
import pathlib
import platform
import re
import socket
import statistics
import subprocess
import time

PROJECT = pathlib.Path(__file__).resolve().parent.parent
BENCHMARKS = PROJECT / "docs" / "benchmarks.md"


def free_port():
    """A TCP port free on this machine now (for a private roscore)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def median_time(f, repeats=7, warmup=1):
    """Median wall time of f() in seconds over `repeats` calls after `warmup` calls."""
    for _ in range(warmup):
        f()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def machine_line():
    """One line naming the CPU, cores and software versions the figures were measured on."""
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    pcl = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "libpcl-dev"], capture_output=True, text=True).stdout
    import numpy

    return (f"{cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, NumPy {numpy.__version__}, "
            f"PCL {pcl or '?'}; {time.strftime('%Y-%m-%d')}")


def ms(seconds):
    return f"{seconds * 1e3:.2f} ms"


def table(header, rows):
    """A markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def write_figures(name, text):
    """Replaces the text between <!-- bench:NAME --> and <!-- /bench:NAME --> in docs/benchmarks.md with text."""
    start, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    page = BENCHMARKS.read_text()
    pattern = re.compile(re.escape(start) + ".*?" + re.escape(end), re.S)
    if not pattern.search(page):
        print(f"docs/benchmarks.md has no {start} ... {end} markers; figures not written there")
        return
    BENCHMARKS.write_text(pattern.sub(lambda _: f"{start}\n{text}\n{end}", page))
    print(f"figures written to docs/benchmarks.md ({name})")
