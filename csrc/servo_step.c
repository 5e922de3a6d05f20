/* One period of the DifferentialIkServo's resolved-rate control, and the pose error it
 * closes: the compiled kernel of guidedarm.systems.path_following.differential_ik_servo_math,
 * whose module docstring gives the mathematics (the same operations, in the same order,
 * except the eigen-decomposition: cyclic Jacobi here, LAPACK's dsyevd in the reference).
 * tests/differential_ik_servo_reference.py holds the numpy reference that
 * tests/test_differential_ik_servo_kernel.py compares this with.
 *
 * PoseError(X_current, X_desired, out): [rotation vector; translation] (rad, m; in W)
 *   taking X_current to X_desired, both 3 x 4 row-major [R | p] (12 doubles); out (6).
 * ServoStep(J, error, twist, q, v, period, lower, upper, speed, acceleration, R_WT,
 *           weights, damping, gain, q_next, v_next) -> limited (bool)
 *   J (6 x n, row-major), error (6), twist (6, or empty: none), q, v (n), period (s), the
 *   limits (n each), R_WT (3 x 3 row-major), weights (6), damping, gain; q_next and v_next
 *   (n) written.
 * ServoPeriod(J, M_WT, M_WD, previous, feedforward, q, v, period, lower, upper, speed,
 *             acceleration, weights, damping, gain, q_next, v_next) -> (limited, stop)
 *   the DifferentialIkServo's period in one call: ServoStep with error = PoseError(M_WT,
 *   M_WD), twist = PoseError(previous, M_WD) * feedforward (none when feedforward is 0 or
 *   previous[0] is NaN) and R_WT = M_WT's rotation; M_WT, M_WD, previous 3 x 4 row-major
 *   (12); stop (a list): where each joint comes to rest braking from v_next at its
 *   acceleration limit, q_next + v_next |v_next| / (2 acceleration).
 * All float64 buffers, C-contiguous. */

#include "buffers.h"  /* Python.h first, as Python's C API asks */

#include <math.h>

#define MAX_JOINTS 16
/* As differential_ik_servo_math. */
#define FEEDBACK_ACCELERATION_SHARE 0.5
#define CENTRING_SPEED_SHARE 0.3
#define MIN_DAMPING 1e-3

static void PoseErrorOf(const double *C, const double *D, double *out) {
    /* R = R_D R_C', then its rotation vector through the unit quaternion (Shepperd's
     * choice of the largest of 1 + trace and the diagonal, w >= 0), as Drake's
     * RotationMatrix::ToAngleAxis does. */
    double R[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            R[i][j] = D[4 * i] * C[4 * j] + D[4 * i + 1] * C[4 * j + 1] + D[4 * i + 2] * C[4 * j + 2];
    double trace = R[0][0] + R[1][1] + R[2][2];
    double w, x, y, z;
    if (trace >= R[0][0] && trace >= R[1][1] && trace >= R[2][2]) {
        w = 1 + trace;
        x = R[2][1] - R[1][2];
        y = R[0][2] - R[2][0];
        z = R[1][0] - R[0][1];
    } else if (R[0][0] >= R[1][1] && R[0][0] >= R[2][2]) {
        w = R[2][1] - R[1][2];
        x = 1 - (trace - 2 * R[0][0]);
        y = R[0][1] + R[1][0];
        z = R[0][2] + R[2][0];
    } else if (R[1][1] >= R[2][2]) {
        w = R[0][2] - R[2][0];
        x = R[0][1] + R[1][0];
        y = 1 - (trace - 2 * R[1][1]);
        z = R[1][2] + R[2][1];
    } else {
        w = R[1][0] - R[0][1];
        x = R[0][2] + R[2][0];
        y = R[1][2] + R[2][1];
        z = 1 - (trace - 2 * R[2][2]);
    }
    if (w < 0) {
        w = -w;
        x = -x;
        y = -y;
        z = -z;
    }
    double norm = sqrt(w * w + x * x + y * y + z * z);
    w /= norm;
    x /= norm;
    y /= norm;
    z /= norm;
    double vec = sqrt(x * x + y * y + z * z);
    double scale = vec > 0 ? 2 * atan2(vec, w) / vec : 2.0;  /* angle / |vec|, 2 at 0 */
    out[0] = x * scale;
    out[1] = y * scale;
    out[2] = z * scale;
    for (int i = 0; i < 3; ++i) out[3 + i] = D[4 * i + 3] - C[4 * i + 3];
}

/* Eigenvalues e and eigenvectors (columns of V) of the symmetric n x n matrix A (row-major,
 * overwritten) by cyclic Jacobi rotations. Returns 0 if A is not finite. */
static int SymmetricEigen(int n, double *A, double *e, double *V) {
    for (int i = 0; i < n * n; ++i)
        if (!isfinite(A[i])) return 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) V[i * n + j] = i == j;
    for (int sweep = 0; sweep < 100; ++sweep) {
        double off = 0, diagonal = 0;
        for (int p = 0; p < n; ++p) {
            diagonal += A[p * n + p] * A[p * n + p];
            for (int q = p + 1; q < n; ++q) off += A[p * n + q] * A[p * n + q];
        }
        if (off <= 1e-36 * diagonal || off == 0) break;
        for (int p = 0; p < n; ++p) {
            for (int q = p + 1; q < n; ++q) {
                double apq = A[p * n + q];
                if (apq == 0) continue;
                double theta = (A[q * n + q] - A[p * n + p]) / (2 * apq);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int r = 0; r < n; ++r) {  /* columns p, q */
                    double arp = A[r * n + p], arq = A[r * n + q];
                    A[r * n + p] = c * arp - s * arq;
                    A[r * n + q] = s * arp + c * arq;
                }
                for (int r = 0; r < n; ++r) {  /* rows p, q */
                    double apr = A[p * n + r], aqr = A[q * n + r];
                    A[p * n + r] = c * apr - s * aqr;
                    A[q * n + r] = s * apr + c * aqr;
                }
                A[p * n + q] = A[q * n + p] = 0;
                for (int r = 0; r < n; ++r) {
                    double vrp = V[r * n + p], vrq = V[r * n + q];
                    V[r * n + p] = c * vrp - s * vrq;
                    V[r * n + q] = s * vrp + c * vrq;
                }
            }
        }
    }
    for (int i = 0; i < n; ++i) e[i] = A[i * n + i];
    return 1;
}

static PyObject *PoseError(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer C, D, out;
    if (!PyArg_ParseTuple(args, "y*y*w*", &C, &D, &out)) return NULL;
    PyObject *result = NULL;
    if (Doubles(&C, 12, "X_current") && Doubles(&D, 12, "X_desired") && Doubles(&out, 6, "out")) {
        PoseErrorOf(C.buf, D.buf, out.buf);
        result = Py_None;
        Py_INCREF(result);
    }
    PyBuffer_Release(&C);
    PyBuffer_Release(&D);
    PyBuffer_Release(&out);
    return result;
}

/* One period (ServoStep): q_next and v_next written; 1 when a limit bound v_next, else 0;
 * -1 when J or the error is not finite. twist NULL: none; R_WT's rows r_stride apart. */
static int Step(Py_ssize_t n, const double *J, const double *error, const double *twist,
                const double *q, const double *v, double period, const double *lower,
                const double *upper, const double *speed, const double *acceleration,
                const double *R, int r_stride, const double *weights, double damping,
                double gain, double *q_next, double *v_next) {
    int with_twist = twist != NULL;
    int m = (int)n + 1 + with_twist;
    /* [J error twist] expressed in T (each 3-row half rotated by R_WT'), rows weighted. */
    double A[6][MAX_JOINTS + 2];
    for (int half = 0; half < 2; ++half) {
        for (int i = 0; i < 3; ++i) {
            for (int c = 0; c < m; ++c) {
                double column[3];
                for (int k = 0; k < 3; ++k) {
                    int row = 3 * half + k;
                    column[k] = c < n ? J[row * n + c] : (c == n ? error[row] : twist[row]);
                }
                double a = R[i] * column[0] + R[r_stride + i] * column[1] +
                           R[2 * r_stride + i] * column[2];
                A[3 * half + i][c] = a * weights[3 * half + i];
            }
        }
    }
    /* The normal equations: N = A_J' A_J (n x n), b = A_J' [error twist]. */
    double N[MAX_JOINTS * MAX_JOINTS], b[MAX_JOINTS][2];
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < m; ++c) {
            double s = 0;
            for (int r = 0; r < 6; ++r) s += A[r][i] * A[r][c];
            if (c < n)
                N[i * n + c] = s;
            else
                b[i][c - n] = s;
        }
    }
    double e[MAX_JOINTS], V[MAX_JOINTS * MAX_JOINTS];
    if (!SymmetricEigen((int)n, N, e, V)) return -1;
    double e_min = e[0];
    for (int i = 1; i < n; ++i) e_min = e[i] < e_min ? e[i] : e_min;
    double lam2 = damping * damping - (e_min > 0 ? e_min : 0.0);
    if (lam2 < MIN_DAMPING * MIN_DAMPING) lam2 = MIN_DAMPING * MIN_DAMPING;
    /* Right-hand sides: the centring velocity times lam2, the error's and the twist's. */
    double rhs[MAX_JOINTS][3];
    for (int i = 0; i < n; ++i) {
        double middle = 0.5 * (lower[i] + upper[i]);
        double half_range = 0.5 * (upper[i] - lower[i]);
        half_range = half_range > 1e-9 ? half_range : 1e-9;
        double x = (middle - q[i]) / half_range;
        x = x < -1.0 ? -1.0 : (x > 1.0 ? 1.0 : x);
        rhs[i][0] = lam2 * (CENTRING_SPEED_SHARE * speed[i] * pow(x, 3.0));
        rhs[i][1] = b[i][0];
        rhs[i][2] = with_twist ? b[i][1] : 0.0;
    }
    /* x = V diag(1 / (e + lam2)) V' rhs, for the centring, feedback and feedforward. */
    double solved[3][MAX_JOINTS];
    for (int c = 0; c < 3; ++c) {
        double projected[MAX_JOINTS];
        for (int k = 0; k < n; ++k) {
            double s = 0;
            for (int i = 0; i < n; ++i) s += V[i * n + k] * rhs[i][c];
            projected[k] = s / (e[k] + lam2);
        }
        for (int i = 0; i < n; ++i) {
            double s = 0;
            for (int k = 0; k < n; ++k) s += V[i * n + k] * projected[k];
            solved[c][i] = s;
        }
    }
    const double *v_c = solved[0], *dq = solved[1], *feedforward = solved[2];
    double reach = 0;
    for (int i = 0; i < n; ++i) {
        double r = fabs(dq[i]) / (FEEDBACK_ACCELERATION_SHARE * acceleration[i]);
        reach = r > reach ? r : reach;
    }
    double scale = gain;
    if (reach > 0 && sqrt(2.0 / reach) < gain) scale = sqrt(2.0 / reach);
    double wanted[MAX_JOINTS], speed_ratio = INFINITY;
    for (int i = 0; i < n; ++i) {
        wanted[i] = v_c[i] + dq[i] * scale;
        if (with_twist) wanted[i] += feedforward[i];
        double w = fabs(wanted[i]);
        double ratio = speed[i] / (w < 1e-300 ? 1e-300 : w);
        speed_ratio = ratio < speed_ratio ? ratio : speed_ratio;
    }
    double excess = 0;
    for (int i = 0; i < n; ++i) {
        if (speed_ratio < 1.0) wanted[i] *= speed_ratio;
        double r = fabs(wanted[i] - v[i]) / (acceleration[i] * period);
        excess = r > excess ? r : excess;
    }
    /* v + (wanted - v) scaled into the acceleration limits, then braking before the
     * position limits. */
    for (int i = 0; i < n; ++i) {
        double vi = excess > 1.0 ? v[i] + (wanted[i] - v[i]) / excess : v[i] + (wanted[i] - v[i]);
        double to_upper = upper[i] - q[i], to_lower = q[i] - lower[i];
        double a2 = 2 * acceleration[i];
        double high = sqrt(a2 * (to_upper < 0.0 ? 0.0 : to_upper));
        if (to_upper / period < high) high = to_upper / period;
        double low = -sqrt(a2 * (to_lower < 0.0 ? 0.0 : to_lower));
        if (-to_lower / period > low) low = -to_lower / period;
        if (low > high) high = low;
        if (low > vi) vi = low;
        if (high < vi) vi = high;
        v_next[i] = vi;
        q_next[i] = q[i] + vi * period;
    }
    return excess > 1.0 || speed_ratio < 1.0;
}

static PyObject *ServoStep(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer Jb, errorb, twistb, qb, vb, lowerb, upperb, speedb, accelerationb, Rb, weightsb,
        q_nextb, v_nextb;
    double period, damping, gain;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*dy*y*y*y*y*y*ddw*w*", &Jb, &errorb, &twistb, &qb,
                          &vb, &period, &lowerb, &upperb, &speedb, &accelerationb, &Rb,
                          &weightsb, &damping, &gain, &q_nextb, &v_nextb))
        return NULL;
    Py_buffer *all[] = {&Jb, &errorb, &twistb, &qb, &vb, &lowerb, &upperb,
                        &speedb, &accelerationb, &Rb, &weightsb, &q_nextb, &v_nextb};
    PyObject *result = NULL;
    Py_ssize_t n = qb.len / (Py_ssize_t)sizeof(double);
    int with_twist = twistb.len > 0;
    if (n < 1 || n > MAX_JOINTS) {
        PyErr_Format(PyExc_ValueError, "q: 1 to %d joints, got %zd", MAX_JOINTS, n);
        goto done;
    }
    if (!Doubles(&Jb, 6 * n, "J") || !Doubles(&errorb, 6, "error") ||
        (with_twist && !Doubles(&twistb, 6, "twist")) || !Doubles(&vb, n, "v") ||
        !Doubles(&lowerb, n, "lower") || !Doubles(&upperb, n, "upper") ||
        !Doubles(&speedb, n, "speed") || !Doubles(&accelerationb, n, "acceleration") ||
        !Doubles(&Rb, 9, "R_WT") || !Doubles(&weightsb, 6, "weights") ||
        !Doubles(&q_nextb, n, "q_next") || !Doubles(&v_nextb, n, "v_next"))
        goto done;
    int limited = Step(n, Jb.buf, errorb.buf, with_twist ? twistb.buf : NULL, qb.buf, vb.buf,
                       period, lowerb.buf, upperb.buf, speedb.buf, accelerationb.buf, Rb.buf, 3,
                       weightsb.buf, damping, gain, q_nextb.buf, v_nextb.buf);
    if (limited < 0)
        PyErr_SetString(PyExc_ValueError, "ServoStep: the Jacobian or the error is not finite");
    else
        result = PyBool_FromLong(limited);
done:
    for (size_t k = 0; k < sizeof(all) / sizeof(all[0]); ++k) PyBuffer_Release(all[k]);
    return result;
}

static PyObject *ServoPeriod(PyObject *self, PyObject *args) {
    (void)self;
    Py_buffer Jb, Cb, Db, previousb, qb, vb, lowerb, upperb, speedb, accelerationb, weightsb,
        q_nextb, v_nextb;
    double feedforward, period, damping, gain;
    if (!PyArg_ParseTuple(args, "y*y*y*y*dy*y*dy*y*y*y*y*ddw*w*", &Jb, &Cb, &Db, &previousb,
                          &feedforward, &qb, &vb, &period, &lowerb, &upperb, &speedb,
                          &accelerationb, &weightsb, &damping, &gain, &q_nextb, &v_nextb))
        return NULL;
    Py_buffer *all[] = {&Jb, &Cb, &Db, &previousb, &qb, &vb, &lowerb,
                        &upperb, &speedb, &accelerationb, &weightsb, &q_nextb, &v_nextb};
    PyObject *result = NULL;
    Py_ssize_t n = qb.len / (Py_ssize_t)sizeof(double);
    if (n < 1 || n > MAX_JOINTS) {
        PyErr_Format(PyExc_ValueError, "q: 1 to %d joints, got %zd", MAX_JOINTS, n);
        goto done;
    }
    if (!Doubles(&Jb, 6 * n, "J") || !Doubles(&Cb, 12, "M_WT") || !Doubles(&Db, 12, "M_WD") ||
        !Doubles(&previousb, 12, "previous") || !Doubles(&vb, n, "v") ||
        !Doubles(&lowerb, n, "lower") || !Doubles(&upperb, n, "upper") ||
        !Doubles(&speedb, n, "speed") || !Doubles(&accelerationb, n, "acceleration") ||
        !Doubles(&weightsb, 6, "weights") || !Doubles(&q_nextb, n, "q_next") ||
        !Doubles(&v_nextb, n, "v_next"))
        goto done;
    const double *previous = previousb.buf, *acceleration = accelerationb.buf;
    double error[6], twist[6];
    PoseErrorOf(Cb.buf, Db.buf, error);
    int with_twist = feedforward != 0 && !isnan(previous[0]);
    if (with_twist) {
        PoseErrorOf(previous, Db.buf, twist);
        for (int i = 0; i < 6; ++i) twist[i] *= feedforward;
    }
    double *q_next = q_nextb.buf, *v_next = v_nextb.buf;
    int limited = Step(n, Jb.buf, error, with_twist ? twist : NULL, qb.buf, vb.buf, period,
                       lowerb.buf, upperb.buf, speedb.buf, acceleration, Cb.buf, 4,
                       weightsb.buf, damping, gain, q_next, v_next);
    if (limited < 0) {
        PyErr_SetString(PyExc_ValueError, "ServoPeriod: the Jacobian or the error is not finite");
        goto done;
    }
    PyObject *stop = PyList_New(n);
    if (!stop) goto done;
    for (Py_ssize_t i = 0; i < n; ++i) {
        PyObject *at = PyFloat_FromDouble(q_next[i] +
                                          v_next[i] * fabs(v_next[i]) / (2 * acceleration[i]));
        if (!at) {
            Py_DECREF(stop);
            goto done;
        }
        PyList_SET_ITEM(stop, i, at);
    }
    result = Py_BuildValue("(NN)", PyBool_FromLong(limited), stop);
done:
    for (size_t k = 0; k < sizeof(all) / sizeof(all[0]); ++k) PyBuffer_Release(all[k]);
    return result;
}

static PyMethodDef kMethods[] = {
    {"PoseError", PoseError, METH_VARARGS, "The pose error (see the module source)."},
    {"ServoStep", ServoStep, METH_VARARGS, "One servo period (see the module source)."},
    {"ServoPeriod", ServoPeriod, METH_VARARGS,
     "The DifferentialIkServo's period in one call (see the module source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kModule = {
    PyModuleDef_HEAD_INIT, "_servo_step", "Compiled kernel of differential_ik_servo_math.", -1,
    kMethods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__servo_step(void) { return PyModule_Create(&kModule); }
