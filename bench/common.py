"""Helpers shared by the benchmarks: timing, the machine line, tables, writing figures into docs pages,
process CPU time, a roscore of their own."""
import contextlib
import os
import pathlib
import platform
import re
import signal
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


def write_section(path, name, text):
    """Replaces the text between <!-- bench:NAME --> and <!-- /bench:NAME --> in the markdown file
    `path` with text (atomically); a file without the markers is left alone."""
    path = pathlib.Path(path)
    start, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    page = path.read_text() if path.exists() else ""
    pattern = re.compile(re.escape(start) + ".*?" + re.escape(end), re.S)
    if not pattern.search(page):
        print(f"{path.name} has no {start} ... {end} markers; figures not written there")
        return
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(pattern.sub(lambda _: f"{start}\n{text}\n{end}", page))
    os.replace(tmp, path)
    print(f"figures written to {path.relative_to(PROJECT) if path.is_relative_to(PROJECT) else path} ({name})")


def write_figures(name, text):
    """Replaces the text between <!-- bench:NAME --> and <!-- /bench:NAME --> in docs/benchmarks.md with text."""
    write_section(BENCHMARKS, name, text)


def cpu_seconds(pid):
    """User + system CPU time of a process (all its threads), seconds."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def machine_busy_seconds():
    """CPU seconds all processes on the machine have used: every /proc/stat column but idle and iowait."""
    with open("/proc/stat") as f:
        values = [int(v) for v in f.readline().split()[1:]]
    return (sum(values) - values[3] - values[4]) / os.sysconf("SC_CLK_TCK")


def stop(*processes, timeout=20):
    """SIGINT to each process still running (a node's clean Ctrl-C), SIGKILL after timeout (s)."""
    for proc in processes:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                proc.kill()


@contextlib.contextmanager
def own_roscore(tmp):
    """A roscore of the benchmark's own on a free port (ROS_HOME under the folder tmp), so other work's
    masters are left alone; its URI is put in os.environ. Yields the environment for child processes;
    stops the roscore (its whole process group) at the end."""
    port = free_port()
    uri = dict(ROS_MASTER_URI=f"http://localhost:{port}", ROS_HOME=os.path.join(tmp, "ros_home"))
    env = dict(os.environ, **uri)
    os.environ.update(uri)
    roscore = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        import rosgraph

        deadline = time.monotonic() + 30
        while not rosgraph.is_master_online():
            if time.monotonic() > deadline:
                raise RuntimeError("roscore did not start")
            time.sleep(0.2)
        yield env
    finally:
        os.killpg(roscore.pid, signal.SIGINT)
        try:
            roscore.wait(20)
        except subprocess.TimeoutExpired:
            os.killpg(roscore.pid, signal.SIGKILL)
