"""Verification of the generated C (spec 60): ``pipeline`` (the stages), ``compare``,
``harness``, ``firmware_compare`` and ``samples``.

The API function that runs it is :func:`armgen.verify` (:func:`armgen.api.verify`); this
layer is the sub-package ``armgen.verification``, a different name, so that neither hides the
other.
"""
