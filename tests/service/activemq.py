"""A real ActiveMQ broker for tests: Debian's ``activemq`` (Java), started
with a minimal configuration of its own on a free loopback port.

Only a STOMP transport connector (no OpenWire, web console or JMX),
persistence off, small memory. :func:`start_broker` waits until the port
accepts connections; :meth:`Broker.stop` ends the whole process group.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

#: Where Debian's package puts the broker (``/usr/bin/activemq`` is its script).
ACTIVEMQ_HOME = Path("/usr/share/activemq")

#: Bytes of one STOMP frame the test broker accepts (above the service's
#: message_bytes, so the bridge's own limit is what refuses a big message).
MAX_FRAME_BYTES = 1024 * 1024

_CONFIG = """<beans xmlns="http://www.springframework.org/schema/beans"
  xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
  xsi:schemaLocation="http://www.springframework.org/schema/beans
    http://www.springframework.org/schema/beans/spring-beans-2.0.xsd
    http://activemq.apache.org/schema/core
    http://activemq.apache.org/schema/core/activemq-core.xsd">
  <broker xmlns="http://activemq.apache.org/schema/core" brokerName="realizer-test"
          useJmx="false" persistent="false" advisorySupport="false"
          dataDirectory="{data}">
    <systemUsage><systemUsage>
      <memoryUsage><memoryUsage limit="32 mb"/></memoryUsage>
      <tempUsage><tempUsage limit="64 mb"/></tempUsage>
    </systemUsage></systemUsage>
    <transportConnectors>
      <transportConnector name="stomp"
        uri="stomp://127.0.0.1:{port}?transport.maxFrameSize={frame}"/>
    </transportConnectors>
  </broker>
</beans>
"""


def missing() -> str | None:
    """Why no broker can be started here, or None."""
    if shutil.which("java") is None:
        return "no java (Debian's activemq needs it: apt-get install activemq)"
    if not (ACTIVEMQ_HOME / "bin" / "activemq.jar").exists():
        return f"no ActiveMQ in {ACTIVEMQ_HOME} (apt-get install activemq)"
    return None


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@dataclass
class Broker:
    port: int
    process: subprocess.Popen[bytes]
    log: Path
    started_seconds: float

    @property
    def url(self) -> str:
        return f"stomp://127.0.0.1:{self.port}"

    def stop(self) -> None:
        """End the broker's whole process group (the JVM and anything it started)."""
        if self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGTERM)
                self.process.wait(10)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait(10)


def start_broker(folder: Path, timeout: float = 60.0) -> Broker:
    """A broker whose configuration, data and log live in ``folder``."""
    port = free_port()
    data = folder / "data"
    data.mkdir(parents=True, exist_ok=True)
    config = folder / "activemq.xml"
    config.write_text(_CONFIG.format(data=data, port=port, frame=MAX_FRAME_BYTES))
    log = folder / "broker.log"
    command = [
        "java",
        "-Xms32m",
        "-Xmx128m",
        f"-Dactivemq.home={ACTIVEMQ_HOME}",
        f"-Dactivemq.base={folder}",
        f"-Dactivemq.conf={folder}",
        f"-Dactivemq.data={data}",
        "-jar",
        str(ACTIVEMQ_HOME / "bin" / "activemq.jar"),
        "start",
        f"xbean:file:{config}",
    ]
    began = time.monotonic()
    with log.open("wb") as out:
        process = subprocess.Popen(
            command, stdout=out, stderr=subprocess.STDOUT, start_new_session=True, cwd=folder
        )
    broker = Broker(port, process, log, 0.0)
    deadline = began + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            tail = log.read_text()[-2000:]
            raise RuntimeError(f"activemq exited with {process.returncode}: {tail}")
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.5):
                broker.started_seconds = time.monotonic() - began
                return broker
        except OSError:
            time.sleep(0.1)
    broker.stop()
    tail = log.read_text()[-2000:]
    raise RuntimeError(f"activemq did not open port {port} in {timeout} s: {tail}")
