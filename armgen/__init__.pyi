# Types of the root package's lazy exports (armgen/__init__.py imports them on first use).
# A stub rather than an `if TYPE_CHECKING:` block: the root then has no import of any layer,
# and every layer may import __version__ from it (tests/test_layers.py).
from .api import Generated as Generated, Plan as Plan, VerifyReport as VerifyReport, generate as generate, \
    plan as plan, verify as verify
from .errors import ArmgenError as ArmgenError, PlanningError as PlanningError, RobotFileError as RobotFileError, \
    TaskFileError as TaskFileError, ToolchainError as ToolchainError, VerificationError as VerificationError
from .robot import Joint as Joint, Robot as Robot, load_robot as load_robot

__version__: str
__all__: list[str]
