/* The compiled kernel of ${p}.c (${precision}): each function evaluated on `count` samples in one
 * call, as a CPython extension module (written by armgen into its kernel store; not part of the
 * generated code): behind armgen's Python API (double) and the verifier's callbacks stage. Every
 * argument after `count` is a C-contiguous buffer of ${p}_real: an input holds one sample's values
 * (used for every sample) or `count` samples' one after another, an output `count` samples';
 * each sample column-major. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>
#include "${p}.h"

/* Batches of at least this many samples run with the GIL released: releasing it costs about
 * what one sample of the kinematics does. */
#define ${P}_API_RELEASE_GIL_SAMPLES 64

/* Acquire argument `position`'s buffer and its stride (values per sample; 0: one sample's
 * values for all); 0 on success, -1 with a Python exception set (and nothing held). */
static int ${p}_api_view(PyObject *object, Py_buffer *view, int output, Py_ssize_t count, Py_ssize_t size,
                         Py_ssize_t *stride, Py_ssize_t position) {
  Py_ssize_t values;
  if (PyObject_GetBuffer(object, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (output ? PyBUF_WRITABLE : 0)) != 0) {
    return -1;
  }
  values = view->len / (Py_ssize_t)sizeof(${p}_real);
  if ((view->itemsize == (Py_ssize_t)sizeof(${p}_real)) && (view->format != NULL) && (strcmp(view->format, "${format}") == 0)) {
    if ((size == 0) ? (values == 0) : ((values % size == 0) && (values / size == count))) {
      *stride = size;
      return 0;
    }
    if (!output && (values == size)) {
      *stride = 0;
      return 0;
    }
  }
  PyErr_Format(PyExc_ValueError,
               "argument %zd: a contiguous ${dtype} buffer of %zd samples of %zd values%s expected, got %zd bytes of format '%s'",
               position, count, size, output ? "" : " (or of one sample)", view->len,
               view->format != NULL ? view->format : "B");
  PyBuffer_Release(view);
  return -1;
}

$entries

static PyMethodDef ${p}_api_methods[] = {
$methods
  {NULL, NULL, 0, NULL}
};

static struct PyModuleDef ${p}_api_module = {
  PyModuleDef_HEAD_INIT, "$module", "armgen's compiled kernel of ${p}.c, ${precision} (f(count, inputs..., outputs...))", -1,
  ${p}_api_methods, NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit_$module(void);
PyMODINIT_FUNC PyInit_$module(void) { return PyModule_Create(&${p}_api_module); }
