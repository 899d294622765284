/* appell: calls into a compiled model's entry points from Python without ctypes'
   per-argument conversions (appell.numerics.fastcall). Every pointer argument is an
   integer address (None for NULL); the functions are METH_FASTCALL. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

typedef void (*expr1)(double, const double *, const double *, const double *, const double *, double *);
typedef void (*expr2)(double, const double *, const double *, const double *, const double *, double *, double *);
typedef void (*expr3)(double, const double *, const double *, const double *, const double *, double *, double *,
                      double *);
typedef void (*expr4)(double, const double *, const double *, const double *, const double *, double *, double *,
                      double *, double *);
typedef int (*evaluate_fn)(double, const double *, const double *, const double *, const int *, double,
                           double *, double *);

static void *address(PyObject *x)
{
    return x == Py_None ? NULL : PyLong_AsVoidPtr(x);
}

/* expr(fn, t, q, w, a, p, o0[, o1, o2, o3]): void fn(t, q, w, a, p, o0, ...) of c_function */
static PyObject *expr(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (nargs < 7 || nargs > 10) {
        PyErr_SetString(PyExc_TypeError, "expr(fn, t, q, w, a, p, o0[, o1, o2, o3])");
        return NULL;
    }
    void *ptr[10] = {0};
    for (Py_ssize_t i = 0; i < nargs; ++i) if (i != 1) ptr[i] = address(args[i]);
    double t = PyFloat_AsDouble(args[1]);
    if (PyErr_Occurred()) return NULL;
    switch (nargs - 6) {
    case 1: ((expr1)ptr[0])(t, ptr[2], ptr[3], ptr[4], ptr[5], ptr[6]); break;
    case 2: ((expr2)ptr[0])(t, ptr[2], ptr[3], ptr[4], ptr[5], ptr[6], ptr[7]); break;
    case 3: ((expr3)ptr[0])(t, ptr[2], ptr[3], ptr[4], ptr[5], ptr[6], ptr[7], ptr[8]); break;
    default: ((expr4)ptr[0])(t, ptr[2], ptr[3], ptr[4], ptr[5], ptr[6], ptr[7], ptr[8], ptr[9]);
    }
    Py_RETURN_NONE;
}

/* evaluate(fn, t, y, p, bias, dep, cond_max, dy, lam) -> status of appell_evaluate */
static PyObject *evaluate(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError, "evaluate(fn, t, y, p, bias, dep, cond_max, dy, lam)");
        return NULL;
    }
    void *fn = address(args[0]), *y = address(args[2]), *p = address(args[3]), *bias = address(args[4]);
    void *dep = address(args[5]), *dy = address(args[7]), *lam = address(args[8]);
    double t = PyFloat_AsDouble(args[1]), cond_max = PyFloat_AsDouble(args[6]);
    if (PyErr_Occurred()) return NULL;
    return PyLong_FromLong(((evaluate_fn)fn)(t, y, p, bias, dep, cond_max, dy, lam));
}

static PyMethodDef methods[] = {
    {"expr", (PyCFunction)(void (*)(void))expr, METH_FASTCALL, "call a block function of the model"},
    {"evaluate", (PyCFunction)(void (*)(void))evaluate, METH_FASTCALL, "call appell_evaluate"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_appell_fastcall", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__appell_fastcall(void) { return PyModule_Create(&module); }
