# Types of the root package's lazy exports (armgen/__init__.py imports them on first use).
# A stub rather than an `if TYPE_CHECKING:` block: the root then imports no layer at load time
# (only the ground-floor armgen._version).
from ._version import __version__ as __version__
from .api import Generated as Generated, Plan as Plan, VerifyReport as VerifyReport, generate as generate, \
    plan as plan, verify as verify
from .errors import ArmgenError as ArmgenError, PlanningError as PlanningError, RobotFileError as RobotFileError, \
    TaskFileError as TaskFileError, ToolchainError as ToolchainError, VerificationError as VerificationError
from .robot import Joint as Joint, Robot as Robot, load_robot as load_robot

__all__: list[str]
