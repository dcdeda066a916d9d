/*
 * attica._live: the per-sample path of attica.native.Filter.update, as a CPython method.
 *
 * A live Python loop calls the filter once per sample; through cffi that is a Python frame, three
 * list conversions and thirteen argument conversions. Here one C method reads the three 3-vectors
 * (numpy arrays through the buffer protocol, or any sequence of numbers) and calls the step function
 * of attica._native (att_host_step9) through its address, handed over by attica.native together with
 * the filter and the output record it writes. No filter arithmetic here: the step is the firmware's.
 *
 * Not firmware: compiled with Python's flags (setup.py, attica._build), not firmware/cflags.txt.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <math.h>
#include <stdint.h>
#include <string.h>

typedef uint32_t (*att_live_step_fn)(void *f, float gx, float gy, float gz, float ax, float ay, float az,
                                     float mx, float my, float mz, uint32_t n, int full, void *out);

typedef struct {
    PyObject_HEAD
    att_live_step_fn step; /* att_host_step9 of attica._native */
    void *filter;          /* att_filter_t * */
    void *out;             /* att_output_t * the record of the last update */
    PyObject *keep;        /* what owns filter and out (kept alive as long as this object) */
} att_live_stepper;

/* double to float as numpy's astype(float32) does it: rounded to nearest, beyond the range +-Inf. */
static float att_live_f32(double d)
{
    if (d >= 0x1.ffffffp127) { /* FLT_MAX + half an ulp and up round to +Inf */
        return HUGE_VALF;
    }
    if (d <= -0x1.ffffffp127) {
        return -HUGE_VALF;
    }
    return (float)d;
}

/* Three floats from a numpy array (float64 or float32, 3 contiguous elements) or a sequence. */
static int att_live_vec3(PyObject *obj, const char *name, float v[3])
{
    if (PyObject_CheckBuffer(obj)) {
        Py_buffer b;
        if (PyObject_GetBuffer(obj, &b, PyBUF_FORMAT | PyBUF_C_CONTIGUOUS) == 0) {
            int ok = 0;
            if (b.len == 3 * (Py_ssize_t)sizeof(double) && b.format != NULL && strcmp(b.format, "d") == 0) {
                const double *d = (const double *)b.buf;
                v[0] = att_live_f32(d[0]);
                v[1] = att_live_f32(d[1]);
                v[2] = att_live_f32(d[2]);
                ok = 1;
            } else if (b.len == 3 * (Py_ssize_t)sizeof(float) && b.format != NULL && strcmp(b.format, "f") == 0) {
                memcpy(v, b.buf, 3 * sizeof(float));
                ok = 1;
            }
            PyBuffer_Release(&b);
            if (ok) {
                return 0;
            }
        } else {
            PyErr_Clear();
        }
    }
    {
        PyObject *seq = PySequence_Fast(obj, "");
        Py_ssize_t i;
        if (seq == NULL) {
            PyErr_Format(PyExc_TypeError, "%s must be a sequence of 3 numbers, got %.80s", name,
                         Py_TYPE(obj)->tp_name);
            return -1;
        }
        if (PySequence_Fast_GET_SIZE(seq) != 3) {
            PyErr_Format(PyExc_ValueError, "%s must have 3 components, got %zd", name,
                         PySequence_Fast_GET_SIZE(seq));
            Py_DECREF(seq);
            return -1;
        }
        for (i = 0; i < 3; i++) {
            PyObject *item = PySequence_Fast_GET_ITEM(seq, i);
            double d;
            if (PyBool_Check(item) || PyComplex_Check(item)) {
                PyErr_Format(PyExc_TypeError, "%s must hold real numbers, got %.80s", name,
                             Py_TYPE(item)->tp_name);
                Py_DECREF(seq);
                return -1;
            }
            d = PyFloat_AsDouble(item);
            if (d == -1.0 && PyErr_Occurred()) {
                PyErr_Format(PyExc_TypeError, "%s must hold real numbers, got %.80s", name, Py_TYPE(item)->tp_name);
                Py_DECREF(seq);
                return -1;
            }
            v[i] = att_live_f32(d);
        }
        Py_DECREF(seq);
    }
    return 0;
}

/* update(gyr, acc, mag=None, n=1) -> flags */
static PyObject *att_live_update(PyObject *self_obj, PyObject *const *args, Py_ssize_t nargs)
{
    att_live_stepper *self = (att_live_stepper *)self_obj;
    float g[3];
    float a[3];
    float m[3] = {0.0f, 0.0f, 0.0f};
    unsigned long n = 1ul;
    if (nargs < 2 || nargs > 4) {
        PyErr_SetString(PyExc_TypeError, "update(gyr, acc, mag=None, n=1)");
        return NULL;
    }
    if (att_live_vec3(args[0], "gyr", g) != 0 || att_live_vec3(args[1], "acc", a) != 0) {
        return NULL;
    }
    if (nargs >= 3 && args[2] != Py_None && att_live_vec3(args[2], "mag", m) != 0) {
        return NULL;
    }
    if (nargs == 4) {
        if (PyBool_Check(args[3]) || !PyLong_Check(args[3])) {
            PyErr_SetString(PyExc_ValueError, "n must be a whole number of periods >= 1");
            return NULL;
        }
        n = PyLong_AsUnsignedLong(args[3]);
        if ((n == (unsigned long)-1 && PyErr_Occurred()) || n < 1ul || n > 0xFFFFFFFFul) {
            PyErr_Clear();
            PyErr_SetString(PyExc_ValueError, "n must be a whole number of periods >= 1");
            return NULL;
        }
    }
    return PyLong_FromUnsignedLong(
        self->step(self->filter, g[0], g[1], g[2], a[0], a[1], a[2], m[0], m[1], m[2], (uint32_t)n, 2, self->out));
}

static PyObject *att_live_new(PyTypeObject *type, PyObject *args, PyObject *kwds)
{
    unsigned long long step;
    unsigned long long filter;
    unsigned long long out;
    PyObject *keep;
    att_live_stepper *self;
    static char *names[] = {"step", "filter", "out", "keep", NULL};
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "KKKO", names, &step, &filter, &out, &keep)) {
        return NULL;
    }
    if (step == 0u || filter == 0u || out == 0u) {
        PyErr_SetString(PyExc_ValueError, "Stepper: NULL address");
        return NULL;
    }
    self = (att_live_stepper *)type->tp_alloc(type, 0);
    if (self == NULL) {
        return NULL;
    }
    self->step = (att_live_step_fn)(uintptr_t)step;
    self->filter = (void *)(uintptr_t)filter;
    self->out = (void *)(uintptr_t)out;
    Py_INCREF(keep);
    self->keep = keep;
    return (PyObject *)self;
}

static void att_live_dealloc(att_live_stepper *self)
{
    Py_XDECREF(self->keep);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyMethodDef att_live_methods[] = {
    {"update", (PyCFunction)(void (*)(void))att_live_update, METH_FASTCALL,
     "update(gyr, acc, mag=None, n=1) -> flags: one att_host_step9 into the bound record."},
    {NULL, NULL, 0, NULL}};

static PyTypeObject att_live_type = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "attica._live.Stepper",
    .tp_basicsize = sizeof(att_live_stepper),
    .tp_dealloc = (destructor)att_live_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Stepper(step, filter, out, keep): a filter's per-sample update, bound to its record.",
    .tp_methods = att_live_methods,
    .tp_new = att_live_new,
};

static struct PyModuleDef att_live_module = {PyModuleDef_HEAD_INIT, "attica._live",
                                             "The per-sample path of attica.native.Filter.update.", -1,
                                             NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__live(void)
{
    PyObject *m;
    if (PyType_Ready(&att_live_type) < 0) {
        return NULL;
    }
    m = PyModule_Create(&att_live_module);
    if (m == NULL) {
        return NULL;
    }
    Py_INCREF(&att_live_type);
    if (PyModule_AddObject(m, "Stepper", (PyObject *)&att_live_type) < 0) {
        Py_DECREF(&att_live_type);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
