/* The ranges the ToF tool's sensors read for a hose, and the Gauss-Newton fits of the hose
 * centre (and radius) to measured ranges: the compiled kernel of
 * guidedarm.systems.tof.hose_range_model, whose docstrings give the mathematics (the same
 * operations, in the same order, except the least squares of the radius fit and of a
 * nearly rank-deficient centre fit: one-sided Jacobi SVD here, LAPACK's dgelsd in the
 * reference). This file is the module's entry points; the maths is in hose_range_model.c.
 * tests/hose_range_model_reference.py holds the Python reference that
 * tests/test_hose_range_kernel.py compares this with.
 *
 * model: float64 buffer [emitters (6 x 3); axes (6 x 3); hose_radius; cos, sin of the half
 *   cone angle; rim (cos phi, sin phi) pairs of the boundary rays], all in T (m).
 * PlaneRange(model, k, c, radius) -> float or None
 * CylinderRange(model, k, c, axis, radius) -> float or None
 * Refine(model, c, ranges, sensors, axis, max_shift) -> (x, y, z)
 * RadiusFit(model, c, ranges, sensors, axis, max_shift, min_sensors, starts, miss_slope,
 *           max_miss)
 *   -> ((x, y, z), radius) or None
 * LeastSquares(J, r) -> the fits' least-squares solution (a list) of J x = r, J given as
 *   its rows (at most 6, of 2 or 3 floats): the centre fit's for 2 columns, the radius
 *   fit's for 3 (for the tests).
 * c, axis: 3 floats (axis None: a hose perpendicular to the detection plane); ranges: 6
 * floats (m); sensors: sensor indices 0..5; starts: the start radii as multiples of
 * hose_radius. */

#include "buffers.h" /* Python.h first, as Python's C API asks */

#include <math.h>

#include "hose_range.h"

/* Argument parsing. */

static int ModelFrom(Py_buffer *b, Model *m) {
    Py_ssize_t count = b->len / (Py_ssize_t)sizeof(double);
    Py_ssize_t fixed = 6 * SENSORS + 3;
    if (b->len % (Py_ssize_t)sizeof(double) || count < fixed || (count - fixed) % 2 ||
        (count - fixed) / 2 > MAX_RIM) {
        PyErr_Format(PyExc_ValueError, "model: %zd + 2 x (at most %d) doubles expected, got %zd "
                     "bytes", fixed, MAX_RIM, b->len);
        return 0;
    }
    const double *d = b->buf;
    m->e = d;
    m->z = d + 3 * SENSORS;
    m->radius = d[6 * SENSORS];
    m->cos_half = d[6 * SENSORS + 1];
    m->sin_half = d[6 * SENSORS + 2];
    m->rim = d + fixed;
    m->rim_count = (int)((count - fixed) / 2);
    m->miss_slope = 0, m->max_miss = -1; /* no ranges past the rim: RadiusFit sets them */
    return 1;
}

/* n floats of a sequence into out; 0 with a ValueError or TypeError naming it. */
static int Floats(PyObject *sequence, Py_ssize_t n, const char *name, double *out) {
    PyObject *fast = PySequence_Fast(sequence, name);
    if (!fast) return 0;
    int ok = PySequence_Fast_GET_SIZE(fast) == n;
    if (!ok) PyErr_Format(PyExc_ValueError, "%s: %zd floats expected", name, n);
    for (Py_ssize_t i = 0; ok && i < n; ++i) {
        out[i] = PyFloat_AsDouble(PySequence_Fast_GET_ITEM(fast, i));
        ok = !(out[i] == -1.0 && PyErr_Occurred());
    }
    Py_DECREF(fast);
    return ok;
}

/* The axis (3 floats) or NULL for None. 0 on an error. */
static int AxisFrom(PyObject *object, double *axis, const double **out) {
    *out = NULL;
    if (object == Py_None) return 1;
    if (!Floats(object, 3, "axis", axis)) return 0;
    *out = axis;
    return 1;
}

/* Sensor indices (0..5, at most SENSORS of them); their count, or -1 on an error. */
static int Sensors(PyObject *sequence, int *out) {
    PyObject *fast = PySequence_Fast(sequence, "sensors");
    if (!fast) return -1;
    Py_ssize_t n = PySequence_Fast_GET_SIZE(fast);
    int ok = n <= SENSORS;
    if (!ok) PyErr_Format(PyExc_ValueError, "sensors: at most %d expected", SENSORS);
    for (Py_ssize_t i = 0; ok && i < n; ++i) {
        long k = PyLong_AsLong(PySequence_Fast_GET_ITEM(fast, i));
        ok = !(k == -1 && PyErr_Occurred());
        if (ok && (k < 0 || k >= SENSORS)) {
            PyErr_Format(PyExc_ValueError, "sensors: %ld is not in 0..%d", k, SENSORS - 1);
            ok = 0;
        }
        out[i] = (int)k;
    }
    Py_DECREF(fast);
    return ok ? (int)n : -1;
}

static int SensorIndex(int k) {
    if (0 <= k && k < SENSORS) return 1;
    PyErr_Format(PyExc_ValueError, "k: %d is not in 0..%d", k, SENSORS - 1);
    return 0;
}

/* *range (set by the call that returned hit) or None. */
static PyObject *RangeOrNone(int hit, const double *range) {
    if (hit) return PyFloat_FromDouble(*range);
    Py_RETURN_NONE;
}

static PyObject *Vector(const double *x) { return Py_BuildValue("(ddd)", x[0], x[1], x[2]); }

static PyObject *PlaneRange(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer b;
    int k;
    PyObject *c_object;
    double r, c[3], range = 0;
    if (!PyArg_ParseTuple(args, "y*iOd", &b, &k, &c_object, &r)) return NULL;
    Model m;
    PyObject *result = NULL;
    if (ModelFrom(&b, &m) && SensorIndex(k) && Floats(c_object, 3, "c", c))
        result = RangeOrNone(PlaneRangeOf(&m, k, c, r, &range), &range);
    PyBuffer_Release(&b);
    return result;
}

static PyObject *CylinderRange(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer b;
    int k;
    PyObject *c_object, *axis_object;
    double r, c[3], axis[3], range = 0;
    if (!PyArg_ParseTuple(args, "y*iOOd", &b, &k, &c_object, &axis_object, &r)) return NULL;
    Model m;
    PyObject *result = NULL;
    if (ModelFrom(&b, &m) && SensorIndex(k) && Floats(c_object, 3, "c", c) &&
        Floats(axis_object, 3, "axis", axis))
        result = RangeOrNone(CylinderRangeOf(&m, k, c, axis, r, &range), &range);
    PyBuffer_Release(&b);
    return result;
}

/* The arguments Refine and RadiusFit share. */
typedef struct {
    Model m;
    double c[3], ranges[SENSORS], axis_values[3];
    const double *axis;
    int sensors[SENSORS], count;
} Fit;

static int FitFrom(Py_buffer *b, PyObject *c, PyObject *ranges, PyObject *sensors,
                   PyObject *axis, Fit *fit) {
    return ModelFrom(b, &fit->m) && Floats(c, 3, "c", fit->c) &&
           Floats(ranges, SENSORS, "ranges", fit->ranges) &&
           (fit->count = Sensors(sensors, fit->sensors)) >= 0 &&
           AxisFrom(axis, fit->axis_values, &fit->axis);
}

static PyObject *Refine(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer b;
    PyObject *c, *ranges, *sensors, *axis;
    double max_shift;
    if (!PyArg_ParseTuple(args, "y*OOOOd", &b, &c, &ranges, &sensors, &axis, &max_shift))
        return NULL;
    Fit fit;
    PyObject *result = NULL;
    if (FitFrom(&b, c, ranges, sensors, axis, &fit)) {
        double x[3];
        RefineOf(&fit.m, fit.c, fit.ranges, fit.sensors, fit.count, fit.axis, max_shift, x);
        result = Vector(x);
    }
    PyBuffer_Release(&b);
    return result;
}

static PyObject *RadiusFit(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer b;
    PyObject *c, *ranges, *sensors, *axis, *starts_object;
    double max_shift, miss_slope, max_miss;
    int min_sensors;
    if (!PyArg_ParseTuple(args, "y*OOOOdiOdd", &b, &c, &ranges, &sensors, &axis, &max_shift,
                          &min_sensors, &starts_object, &miss_slope, &max_miss))
        return NULL;
    Fit fit;
    PyObject *result = NULL;
    Py_ssize_t n_starts = PySequence_Size(starts_object);
    double starts[MAX_STARTS];
    if (n_starts < 0 || n_starts > MAX_STARTS) {
        if (!PyErr_Occurred())
            PyErr_Format(PyExc_ValueError, "starts: at most %d expected", MAX_STARTS);
    } else if (FitFrom(&b, c, ranges, sensors, axis, &fit) &&
               Floats(starts_object, n_starts, "starts", starts)) {
        /* The start that fits best (the first of equal misfits, as min()), its centre
         * within max_shift of c. */
        double best_x[3], best_radius = 0, best_misfit = 0;
        int found = 0;
        fit.m.miss_slope = miss_slope, fit.m.max_miss = max_miss;
        if (fit.count >= min_sensors) {
            for (Py_ssize_t s = 0; s < n_starts; ++s) {
                double x[3], radius, misfit;
                if (!RadiusFitFrom(&fit.m, fit.c, starts[s] * fit.m.radius, fit.ranges,
                                   fit.sensors, fit.count, fit.axis, min_sensors, x, &radius,
                                   &misfit) ||
                    !(Distance(x, fit.c) <= max_shift))
                    continue;
                if (!found || misfit < best_misfit) {
                    best_x[0] = x[0], best_x[1] = x[1], best_x[2] = x[2];
                    best_radius = radius, best_misfit = misfit, found = 1;
                }
            }
        }
        if (found) {
            result = Py_BuildValue("((ddd)d)", best_x[0], best_x[1], best_x[2], best_radius);
        } else {
            result = Py_None;
            Py_INCREF(result);
        }
    }
    PyBuffer_Release(&b);
    return result;
}

static PyObject *LeastSquaresOf(PyObject *self, PyObject *args) {
    (void)self;
    PyObject *rows_object, *r_object;
    if (!PyArg_ParseTuple(args, "OO", &rows_object, &r_object)) return NULL;
    PyObject *rows = PySequence_Fast(rows_object, "J");
    if (!rows) return NULL;
    Py_ssize_t m = PySequence_Fast_GET_SIZE(rows);
    Py_ssize_t n = m > 0 ? PySequence_Size(PySequence_Fast_GET_ITEM(rows, 0)) : 0;
    double J[3 * SENSORS], r[SENSORS], x[3];
    int ok = 1 <= m && m <= SENSORS && (n == 2 || n == 3);
    if (!ok && !PyErr_Occurred())
        PyErr_Format(PyExc_ValueError, "J: 1 to %d rows of 2 or 3 floats expected", SENSORS);
    for (Py_ssize_t i = 0; ok && i < m; ++i)
        ok = Floats(PySequence_Fast_GET_ITEM(rows, i), n, "J's rows", J + n * i);
    Py_DECREF(rows);
    if (!ok || !Floats(r_object, m, "r", r)) return NULL;
    if (n == 2)
        LeastSquares2((int)m, J, r, x);
    else
        LeastSquares((int)m, 3, J, r, x);
    return n == 2 ? Py_BuildValue("[dd]", x[0], x[1]) : Py_BuildValue("[ddd]", x[0], x[1], x[2]);
}

static PyMethodDef kMethods[] = {
    {"PlaneRange", PlaneRange, METH_VARARGS, "HoseRangeModel.PlaneRange (module source)."},
    {"CylinderRange", CylinderRange, METH_VARARGS,
     "HoseRangeModel.CylinderRange (module source)."},
    {"Refine", Refine, METH_VARARGS, "HoseRangeModel.Refine (module source)."},
    {"RadiusFit", RadiusFit, METH_VARARGS, "hose_range_model.RadiusFit (module source)."},
    {"LeastSquares", LeastSquaresOf, METH_VARARGS, "The fits' least squares (module source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kModule = {PyModuleDef_HEAD_INIT, "_hose_range",
                                     "Compiled kernel of hose_range_model.", -1, kMethods};

PyMODINIT_FUNC PyInit__hose_range(void) { return PyModule_Create(&kModule); }
