"""Running the stack live under scripts/launch from a Python script: a config
copy for one run, the group's start and stop, and its supervisord's XML-RPC
(what supervisorctl does). Used by scripts/kill-campaign and scripts/multihost.
"""

import os
import re
import signal
import subprocess
import sys
import time
import xmlrpc.client

ROOT = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))


# The stack's default bus, as config::kDefaultLcmUrl (in a private namespace, private).
with open(os.path.join(ROOT, "scripts/lib/default-lcm-url")) as _f:
    DEFAULT_LCM_URL = _f.read().strip()


def in_private_bus(flag_env):
    """Runs the calling script again in a network namespace of its own whose
    loopback carries multicast (a private LCM bus), unless FLAG_ENV is set
    (we are that run). Returns True when in one, False when the machine
    forbids it (not root, no unshare): the host's bus is then used."""
    if os.environ.get(flag_env):
        return True
    if os.geteuid() == 0 and subprocess.run(["unshare", "--net", "true"]).returncode == 0:
        os.environ[flag_env] = "1"
        script = os.path.abspath(sys.argv[0])
        os.execvp("unshare", [
            "unshare", "--net", "sh", "-c", "ip link set lo up && ip link set lo multicast on "
            "&& ip route add 224.0.0.0/4 dev lo && exec \"$@\"", "sh", sys.executable, script
        ] + sys.argv[1:])
    return False


class ConfigCopyError(Exception):
    pass


# The map files a run leaves beside its landmark map (write_config): the
# landmark DB's SQLite file with its WAL, and the appearance map.
MAP_FILES = ("landmarks.vslam-map", "landmarks.vslam-map-wal", "landmarks.vslam-map-shm",
             "appearance.vslam-appearance")


def remove_maps(folder):
    """Deletes MAP_FILES of an earlier run in FOLDER: they would be loaded."""
    for name in MAP_FILES:
        if os.path.exists(os.path.join(folder, name)):
            os.remove(os.path.join(folder, name))


def write_config(path, map_file, scenario_file, speed, duration):
    """config/vslam.yaml with the landmark map at MAP_FILE, the appearance map
    beside it (appearance.vslam-appearance) and the simulator's scenario, speed
    and duration set; written to PATH."""
    text = open(os.path.join(ROOT, "config/vslam.yaml")).read()
    appearance_map = os.path.join(os.path.dirname(map_file), "appearance.vslam-appearance")
    subs = [
        (r"^robot: robot/", f"robot: {ROOT}/config/robot/"),
        (r"map_file: \$XDG_DATA_HOME/vslam/landmarks\.vslam-map", f"map_file: {map_file}"),
        (r"map_file: \$XDG_DATA_HOME/vslam/appearance\.vslam-appearance",
         f"map_file: {appearance_map}"),
        (r"^    scenario: apartment .*$", f"    scenario: {scenario_file}"),
        (r"^    speed: 1\.0 .*$", f"    speed: {speed}"),
        (r"^    duration: 0 .*$", f"    duration: {duration}"),
    ]
    for pattern, repl in subs:
        text, n = re.subn(pattern, repl, text, count=1, flags=re.M)
        if n != 1:
            raise ConfigCopyError(f"could not set '{repl.strip()}' in a copy of "
                                  f"config/vslam.yaml ('{pattern}')")
    with open(path, "w") as f:
        f.write(text)


class UnixStreamTransport(xmlrpc.client.Transport):
    """XML-RPC over supervisord's unix socket."""

    def __init__(self, path, user, password):
        super().__init__()
        self.path, self.auth = path, (user, password)

    def make_connection(self, host):
        import http.client
        import socket
        path = self.path

        class Conn(http.client.HTTPConnection):

            def connect(self):
                self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                self.sock.connect(path)

        return Conn("localhost")

    def send_headers(self, connection, headers):
        import base64
        token = base64.b64encode(f"{self.auth[0]}:{self.auth[1]}".encode()).decode()
        connection.putheader("Authorization", f"Basic {token}")
        super().send_headers(connection, headers)


def supervisor_proxy(conf):
    text = open(conf).read()
    sock = re.search(r"^file=(.*)$", text, re.M).group(1)
    user = re.search(r"^username=(.*)$", text, re.M).group(1)
    password = re.search(r"^password=(.*)$", text, re.M).group(1)
    return xmlrpc.client.ServerProxy("http://localhost",
                                     transport=UnixStreamTransport(sock, user, password))


class LaunchedGroup:
    """`scripts/launch PROFILE ARGS...` in the background, its output in
    LOG_PATH; PREFIX (e.g. ["ip", "netns", "exec", NS]) runs it elsewhere."""

    def __init__(self, profile, args, log_path, env, prefix=()):
        self.log_path = log_path
        self.popen = subprocess.Popen(list(prefix) + [os.path.join(ROOT, "scripts/launch"), profile] +
                                      list(args), stdout=open(log_path, "w"),
                                      stderr=subprocess.STDOUT, env=env)
        self.status = None
        conf = None
        deadline = time.time() + 30
        while conf is None and time.time() < deadline:
            m = re.search(r"supervisorctl -c (\S+) status", open(log_path).read())
            conf = m.group(1) if m else None
            if self.popen.poll() is not None:
                break
            time.sleep(0.2)
        if conf is None:
            self.stop()
            raise RuntimeError(f"scripts/launch did not start (see {log_path})")
        sock = re.sub(r"supervisord\.conf$", "supervisor.sock", conf)
        while not os.path.exists(sock):
            if self.popen.poll() is not None:
                raise RuntimeError(f"scripts/launch exited with {self.popen.returncode} "
                                   f"(see {log_path})")
            time.sleep(0.2)
        self.supervisor = supervisor_proxy(conf).supervisor

    def info(self, name):
        return self.supervisor.getProcessInfo(name)

    def exited_ok(self, name):
        """NAME ended by itself with status 0 (the simulator at the scenario's end)."""
        info = self.info(name)
        return info["statename"] == "EXITED" and info["exitstatus"] == 0

    def running(self):
        return self.popen.poll() is None

    def stop(self, timeout=150):
        """SIGINT, as Ctrl-C: supervisord stops the programs in order. The
        launch's exit status."""
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGINT)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()
        self.status = self.popen.returncode
        return self.status
