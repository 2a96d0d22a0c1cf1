"""Verification of the generated C (spec 60): ``pipeline`` (the stages), ``compare``,
``harness``, ``firmware`` and ``samples``.

The package is also the API function: ``armgen.verify(robot, …)`` calls
:func:`armgen.api.verify`. The function and this subpackage share the name
``armgen.verify``; the root package (``armgen/__init__.py``) makes this package callable
when the import system binds it, so that nothing here imports the API layer above.
"""
