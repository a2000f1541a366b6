"""A one-node Slurm cluster on this machine for the tests, from Debian's ``slurm-wlm`` and
``munge`` (``make test`` installs them): its own munge key and ``munged`` socket, a minimal
slurm.conf on free loopback ports, ``slurmctld -D`` and ``slurmd -D`` in the background, all
in a temporary folder and stopped after. Needs root (slurmd starts the jobs' processes)."""

from __future__ import annotations

import os
import pwd
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

COMMANDS = ("munged", "slurmctld", "slurmd", "sbatch", "squeue", "sinfo", "srun", "scancel")
START_TIMEOUT = 60  # s for the node to become idle


class ClusterError(Exception):
    """The cluster could not start: the reason and the daemons' logs."""


def free_ports(count: int) -> list[int]:
    """``count`` TCP ports free on 127.0.0.1 now."""
    sockets = [socket.socket() for _ in range(count)]
    try:
        for s in sockets:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def slurm_conf(folder: Path, cpus: int) -> str:
    """A minimal slurm.conf: this host (``hostname -s``, at 127.0.0.1) both controller and the
    one node with ``cpus`` CPUs, root running both daemons, state and logs under ``folder``."""
    host = socket.gethostname().split(".")[0]
    controller, node = free_ports(2)
    return f"""ClusterName=fsitest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={controller}
SlurmdPort={node}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket={folder}/munge.socket
CredType=cred/munge
StateSaveLocation={folder}/state
SlurmdSpoolDir={folder}/spool
SlurmctldPidFile={folder}/slurmctld.pid
SlurmdPidFile={folder}/slurmd.pid
SlurmctldLogFile={folder}/slurmctld.log
SlurmdLogFile={folder}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
SlurmdParameters=config_overrides
MpiDefault=none
ReturnToService=2
NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=debug Nodes={host} Default=YES MaxTime=INFINITE State=UP
"""


def slurm_version() -> tuple[int, ...]:
    """Slurm's version (``slurmd -V``: ``slurm 24.11.5`` → (24, 11, 5))."""
    done = subprocess.run(["slurmd", "-V"], capture_output=True, text=True, check=False)
    return tuple(int(part) for part in re.findall(r"\d+", done.stdout)[:3])


class Cluster:
    """The running cluster: ``env`` (the environment with its ``SLURM_CONF``) and the daemons.
    :meth:`start` and :meth:`stop`; :meth:`wait` for a job to leave the queue."""

    def __init__(self) -> None:
        self.folder = Path(tempfile.mkdtemp(prefix="fsi-slurm-"))
        self.env = {**os.environ, "SLURM_CONF": str(self.folder / "slurm.conf")}
        self.daemons: list[subprocess.Popen] = []

    def start(self) -> None:
        """Start munged, slurmctld and slurmd; :class:`ClusterError` if the node is not idle
        within :data:`START_TIMEOUT`."""
        missing = [c for c in COMMANDS if shutil.which(c) is None]
        if missing:
            raise ClusterError(f"{', '.join(missing)} not found: make test installs slurm-wlm")
        for sub in ("state", "spool"):
            (self.folder / sub).mkdir()
        key = self.folder / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o400)
        self._daemon(
            "munged",
            "--foreground",
            "--force",
            f"--socket={self.folder}/munge.socket",
            f"--key-file={key}",
            f"--pid-file={self.folder}/munged.pid",
            f"--log-file={self.folder}/munged.log",
            f"--seed-file={self.folder}/munged.seed",
        )
        self._until(lambda: (self.folder / "munge.socket").exists(), "munged's socket")
        conf = self.folder / "slurm.conf"
        conf.write_text(slurm_conf(self.folder, max(2, os.cpu_count() or 1)))
        if slurm_version() >= (23, 11):  # slurmd needs no cgroups (a chroot has none mounted)
            (self.folder / "cgroup.conf").write_text("CgroupPlugin=disabled\n")
        self._daemon("slurmctld", "-D", "-f", str(conf))
        self._daemon("slurmd", "-D", "-f", str(conf))
        self._until(self._idle, "the node to be idle in sinfo")

    def _daemon(self, *command: str) -> None:
        log = (self.folder / f"{command[0]}.out").open("w")
        self.daemons.append(
            subprocess.Popen(command, env=self.env, stdout=log, stderr=subprocess.STDOUT)
        )

    def _idle(self) -> bool:
        done = self.run("sinfo", "-h", "-o", "%t")
        return done.returncode == 0 and done.stdout.strip() == "idle"

    def _until(self, ready, what: str) -> None:
        deadline = time.monotonic() + START_TIMEOUT
        while not ready():
            ended = [d.args[0] for d in self.daemons if d.poll() is not None]
            if ended or time.monotonic() > deadline:
                why = f"{', '.join(ended)} ended" if ended else f"no {what} in {START_TIMEOUT} s"
                raise ClusterError(f"Slurm did not start ({why}):\n{self.logs()}")
            time.sleep(0.2)

    def logs(self) -> str:
        """The daemons' output and log files' last lines."""
        parts = []
        for path in sorted(self.folder.glob("*.out")) + sorted(self.folder.glob("*.log")):
            lines = path.read_text(errors="replace").splitlines()[-15:]
            parts.append(f"== {path.name}\n" + "\n".join(lines))
        return "\n".join(parts)

    def run(self, *command: str) -> subprocess.CompletedProcess:
        """A Slurm client command against this cluster (bounded: 60 s)."""
        return subprocess.run(
            command, env=self.env, capture_output=True, text=True, timeout=60, check=False
        )

    def wait(self, job: str, timeout: float) -> bool:
        """Wait until ``job`` has left the queue (True) or ``timeout`` s have passed (False)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            done = self.run("squeue", "-h", "-j", job, "-o", "%i")
            if done.returncode != 0 or not done.stdout.strip():
                return True
            time.sleep(1)
        return False

    def stop(self) -> None:
        """Cancel every job, stop the daemons (SIGTERM, then SIGKILL after 10 s) and delete
        the folder."""
        if self.daemons:
            self.run("scancel", "-u", pwd.getpwuid(os.getuid()).pw_name)
        for daemon in reversed(self.daemons):
            daemon.send_signal(signal.SIGTERM)
        for daemon in reversed(self.daemons):
            try:
                daemon.wait(10)
            except subprocess.TimeoutExpired:
                daemon.kill()
                daemon.wait()
        shutil.rmtree(self.folder, ignore_errors=True)
