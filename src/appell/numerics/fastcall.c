/* appell: calls into a compiled model's entry points from Python without ctypes'
   per-argument conversions (appell.numerics.fastcall). Every pointer argument is an
   integer address (None for NULL); the functions are METH_FASTCALL. */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

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

typedef void (*forward_fn)(double, const double *, const double *, const double *, const double *, double *,
                           double *, double *);

/* the data of x when it is an aligned C-contiguous float64 array of `count` entries, else NULL */
static const double *doubles(PyObject *x, npy_intp count)
{
    if (!PyArray_Check(x)) return NULL;
    PyArrayObject *arr = (PyArrayObject *)x;
    if (PyArray_TYPE(arr) != NPY_DOUBLE || !PyArray_IS_C_CONTIGUOUS(arr) || !PyArray_ISALIGNED(arr) ||
        PyArray_SIZE(arr) != count)
        return NULL;
    return (const double *)PyArray_DATA(arr);
}

/* forward(fn, t, q, w, p, nq, n, np, s, nb) -> (acc, lam, wrench) of appell_forward, new arrays;
   1 where q, w or p is not a contiguous float64 array of its length (the caller converts it or
   names it), 2 where the split failed (NaN accelerations: the caller takes the general route) */
static PyObject *forward(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 10) {
        PyErr_SetString(PyExc_TypeError, "forward(fn, t, q, w, p, nq, n, np, s, nb)");
        return NULL;
    }
    void *fn = address(args[0]);
    double t = PyFloat_AsDouble(args[1]);
    npy_intp size[5];
    for (int i = 0; i < 5; ++i) size[i] = PyLong_AsSsize_t(args[5 + i]);
    if (PyErr_Occurred()) return NULL;
    const double *q = doubles(args[2], size[0]), *w = doubles(args[3], size[1]), *p = doubles(args[4], size[2]);
    if (!q || !w || !p) return PyLong_FromLong(1);
    npy_intp shape[2] = {size[4], 6};
    PyObject *acc = PyArray_SimpleNew(1, &size[1], NPY_DOUBLE), *lam = PyArray_SimpleNew(1, &size[3], NPY_DOUBLE);
    PyObject *wrench = PyArray_SimpleNew(2, shape, NPY_DOUBLE);
    if (!acc || !lam || !wrench) {
        Py_XDECREF(acc); Py_XDECREF(lam); Py_XDECREF(wrench);
        return NULL;
    }
    double *a = PyArray_DATA((PyArrayObject *)acc);
    ((forward_fn)fn)(t, q, w, NULL, p, a, PyArray_DATA((PyArrayObject *)lam), PyArray_DATA((PyArrayObject *)wrench));
    if (size[1] > 0 && a[0] != a[0]) {
        Py_DECREF(acc); Py_DECREF(lam); Py_DECREF(wrench);
        return PyLong_FromLong(2);
    }
    PyObject *out = PyTuple_Pack(3, acc, lam, wrench);
    Py_DECREF(acc); Py_DECREF(lam); Py_DECREF(wrench);
    return out;
}

static PyMethodDef methods[] = {
    {"expr", (PyCFunction)(void (*)(void))expr, METH_FASTCALL, "call a block function of the model"},
    {"evaluate", (PyCFunction)(void (*)(void))evaluate, METH_FASTCALL, "call appell_evaluate"},
    {"forward", (PyCFunction)(void (*)(void))forward, METH_FASTCALL, "call appell_forward on arrays"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_appell_fastcall", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__appell_fastcall(void)
{
    import_array();
    return PyModule_Create(&module);
}
