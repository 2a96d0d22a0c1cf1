"""Verification of the generated C (spec 60): ``pipeline`` (the stages), ``compare``,
``harness``, ``firmware`` and ``samples``.

The package is also the API function: ``armgen.verify(robot, …)`` calls
:func:`armgen.api.verify`. The function and this subpackage share the name
``armgen.verify``, and importing any module of the subpackage rebinds that name to the
package, so the package itself is made callable.
"""

import sys
import types


class _CallablePackage(types.ModuleType):
    def __call__(self, *args, **kwargs):
        from ..api import verify

        return verify(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
