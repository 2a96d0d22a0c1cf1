import shutil

import pytest

from armgen.robot import load_robot

KINEMATIC_ROBOTS = ["planar3", "iiwa14", "panda", "modular8"]


@pytest.fixture(scope="session", params=KINEMATIC_ROBOTS)
def robot(request):
    return load_robot(request.param)


def require_tool(name: str) -> str:
    """Skip (with the install command) when an external tool is missing; CI installs them all."""
    path = shutil.which(name)
    if path is None:
        pytest.skip(f"{name} not installed (apt-get install -y gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm valgrind)")
    return path
