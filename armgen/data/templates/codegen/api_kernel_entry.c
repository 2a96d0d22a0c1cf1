static void ${p}_api_run_$function(Py_ssize_t count, $parameters) {
  Py_ssize_t s;
  for (s = 0; s < count; ++s) (void)${p}_$function($arguments);
}

static PyObject *${p}_api_$function(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
  static const Py_ssize_t sizes[$arity] = {$sizes};
  Py_buffer views[$arity];
  Py_ssize_t strides[$arity];
  Py_ssize_t count;
  Py_ssize_t held = 0;
  (void)module;
  if (nargs != $arity + 1) {
    PyErr_SetString(PyExc_TypeError, "$function takes count and $arity buffers ($names)");
    return NULL;
  }
  count = PyLong_AsSsize_t(args[0]);
  if (count < 0) {
    if (!PyErr_Occurred()) { PyErr_SetString(PyExc_ValueError, "$function: count must be at least 0"); }
    return NULL;
  }
  for (; held < $arity; ++held) {
    if (${p}_api_view(args[held + 1], &views[held], held >= $inputs, count, sizes[held], &strides[held], held + 1) != 0) {
      break;
    }
  }
  if (held == $arity) {
    if (count < ${P}_API_RELEASE_GIL_SAMPLES) {
      ${p}_api_run_$function(count, $call);
    } else {
      Py_BEGIN_ALLOW_THREADS
      ${p}_api_run_$function(count, $call);
      Py_END_ALLOW_THREADS
    }
  }
  while (held > 0) { PyBuffer_Release(&views[--held]); }
  if (PyErr_Occurred()) { return NULL; }
  Py_RETURN_NONE;
}
