import os
import shutil

import pytest

from armgen.robot import load_robot

KINEMATIC_ROBOTS = ["planar3", "iiwa14", "panda", "modular8"]


@pytest.fixture(scope="session", params=KINEMATIC_ROBOTS)
def robot(request):
    return load_robot(request.param)


# The Debian package that brings each external tool the tests use.
TOOL_PACKAGES = {
    "gcc": "gcc", "make": "make", "cmake": "cmake", "arm-none-eabi-gcc": "gcc-arm-none-eabi",
    "arm-none-eabi-nm": "binutils-arm-none-eabi", "qemu-system-arm": "qemu-system-arm",
    "valgrind": "valgrind", "cppcheck": "cppcheck", "ffmpeg": "ffmpeg", "chromium": "chromium",
}


def require_tool(name: str) -> str:
    """The tool's path. Missing locally: skip with the install command. Missing in CI (which
    installs them all, see .ci/run): fail, so a check that did not run is never reported green."""
    path = shutil.which(name)
    if path is None:
        message = f"{name} not installed (apt-get install -y {TOOL_PACKAGES.get(name, name)})"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{message}: CI must install it (.ci/run)")
        pytest.skip(message)
    return path


def terminal_sigint() -> None:
    """SIGINT as a terminal's shell leaves it: default action, not blocked. The Ctrl-C tests
    start from this state: in CI's xdist worker the sweep's tests found SIGINT ignored, so the
    sweep never saw the interrupt. No test leaves it so (a serial run of the whole suite read
    /proc/self/status after every test); a shell without job control starts a background job
    (`.ci/run &`) with SIGINT ignored, and pytest and its workers inherit that. For
    ``preexec_fn`` of a subprocess, or around an in-process sweep."""
    import signal

    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def python_sigint():
    """The main thread's SIGINT as a fresh Python has it (KeyboardInterrupt), restored after."""
    import signal

    previous = signal.getsignal(signal.SIGINT)
    mask = signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
