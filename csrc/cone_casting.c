/* Nearest returns of the ToF cones' rays against primitive shapes, in closed form: the
 * compiled kernel of guidedarm.systems.tof.primitive_ray_casting (SceneRayCaster), which
 * documents the geometry. primitive_ray_casting.FirstHits is the numpy reference of each
 * shape's intersection; tests/test_tof_ray_casting.py compares the two.
 *
 * CastCones(X_WF, p_FS, u_F, z_F, half_angle, reach, kinds, frames, X_FG, sizes, rho,
 *           X_WM, best)
 *   X_WF (12): the sensors' frame F in W, a 3 x 4 row-major [R | p];
 *   p_FS (N, 3), u_F (N, K, 3), z_F (N, 3): the N sensors' origins, K unit rays and axes in F;
 *   half_angle: the cone's half angle (rad, < pi / 2) holding every ray; reach: the rays'
 *   length (m);
 *   kinds (M): each shape's kind (KIND_* below); frames (M): the index of its frame in X_WM,
 *   -1 for the world; X_FG (M, 12): its frame G in that frame; sizes (M, 3) as
 *   primitive_ray_casting.ShapeSizes gives them; rho (M): the radius of a ball about G's
 *   origin holding the shape, with the broadphase's margin;
 *   X_WM (F, 12): the moving frames in W;
 *   best (N), written: each sensor's nearest hit within reach (m), inf for none.
 * All float64 buffers, C-contiguous. A shape is intersected with a sensor's rays only if
 * its ball meets the sensor's cone truncated at reach and comes nearer than the nearest
 * hit so far. */

#include "buffers.h"  /* Python.h first, as Python's C API asks */

#include <math.h>

enum { KIND_BOX = 0, KIND_CAPSULE = 1, KIND_CYLINDER = 2, KIND_HALFSPACE = 3, KIND_SPHERE = 4 };

/* First t >= 0 with t^2 + 2 b t + c = 0 for an origin outside the sphere (c > 0). */
static double SphereEntry(double b, double c) {
    double t = -(b + sqrt(b * b - c));
    return t >= 0 ? t : INFINITY;
}

/* The largest of a, b, NaN if either is (numpy's max). */
static double MaxNan(double a, double b) { return (isnan(a) || a > b) ? a : b; }
static double MinNan(double a, double b) { return (isnan(a) || a < b) ? a : b; }

/* Distance along the unit ray u from o (both in the shape's frame G) to the shape's
 * surface: 0 from inside, inf on a miss or behind o. */
static double FirstHit(int kind, const double *o, const double *u, double ou, const double *s) {
    double ox = o[0], oy = o[1], oz = o[2], ux = u[0], uy = u[1], uz = u[2];
    if (kind == KIND_BOX) {
        double near = -INFINITY, far = INFINITY;
        for (int i = 0; i < 3; ++i) {
            double inverse = 1.0 / u[i];
            double t1 = (-s[i] - o[i]) * inverse, t2 = (s[i] - o[i]) * inverse;
            near = MaxNan(near, fmin(t1, t2));
            far = MinNan(far, fmax(t1, t2));
        }
        near = isnan(near) ? near : (near > 0.0 ? near : 0.0);
        return far >= near ? near : INFINITY;
    }
    if (kind == KIND_HALFSPACE) return oz <= 0 ? 0.0 : (uz < 0 ? -oz / uz : INFINITY);
    double radius2 = s[0] * s[0];
    double rho2 = ox * ox + oy * oy;
    if (kind == KIND_SPHERE) {
        double c = rho2 + oz * oz - radius2;
        return c <= 0 ? 0.0 : SphereEntry(ou, c);
    }
    double half = s[1];
    double minus_a = uz * uz - 1.0;
    double b = ou - oz * uz;
    double t = (b + sqrt(b * b + minus_a * (rho2 - radius2))) / minus_a;
    double z = oz + t * uz;
    double side = (t >= 0 && fabs(z) <= half) ? t : INFINITY;
    if (kind == KIND_CYLINDER) {
        int within = fabs(oz) <= half;
        double end = (double)((oz > 0) - (oz < 0)) * half;
        double t_end = (end - oz) / uz;
        double x = ox + t_end * ux, y = oy + t_end * uy;
        double cap = (t_end >= 0 && x * x + y * y <= radius2 && !within) ? t_end : INFINITY;
        int inside = rho2 <= radius2 && within;
        return inside ? 0.0 : fmin(side, cap);
    }
    /* capsule */
    double centre = z > 0 ? half : -half;
    double beyond = oz - centre;
    double end = SphereEntry(ou - uz * centre, rho2 + beyond * beyond - radius2);
    double out = fabs(oz) - half;
    out = out > 0.0 ? out : 0.0;
    int inside = rho2 + out * out <= radius2;
    return inside ? 0.0 : fmin(side, end);
}

/* A shape to intersect and how near to the sensor its ball comes (m). */
struct Candidate {
    double near;
    Py_ssize_t shape;
};

/* C = A B of 3 x 4 row-major rigid transforms. */
static void Compose(const double *A, const double *B, double *C) {
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 4; ++j) {
            double v = A[4 * i] * B[j] + A[4 * i + 1] * B[4 + j] + A[4 * i + 2] * B[8 + j];
            C[4 * i + j] = j == 3 ? v + A[4 * i + 3] : v;
        }
    }
}

/* R v (+ p) of a 3 x 4 row-major transform. */
static void Rotate(const double *X, const double *v, double *out) {
    for (int i = 0; i < 3; ++i) out[i] = X[4 * i] * v[0] + X[4 * i + 1] * v[1] + X[4 * i + 2] * v[2];
}

static PyObject *CastCones(PyObject *self, PyObject *args) {
    Py_buffer X_WF, p_FS, u_F, z_F, kinds, frames, X_FG, sizes, rho, X_WM, best;
    double half_angle, reach;
    if (!PyArg_ParseTuple(args, "y*y*y*y*ddy*y*y*y*y*y*w*", &X_WF, &p_FS, &u_F, &z_F,
                          &half_angle, &reach, &kinds, &frames, &X_FG, &sizes, &rho, &X_WM,
                          &best))
        return NULL;
    Py_buffer *all[] = {&X_WF, &p_FS, &u_F, &z_F, &kinds, &frames, &X_FG, &sizes, &rho, &X_WM, &best};
    PyObject *result = NULL;
    Py_ssize_t n = best.len / (Py_ssize_t)sizeof(double);
    Py_ssize_t m = kinds.len / (Py_ssize_t)sizeof(double);
    Py_ssize_t f = X_WM.len / (Py_ssize_t)(12 * sizeof(double));
    Py_ssize_t k = n > 0 ? u_F.len / (Py_ssize_t)(3 * n * sizeof(double)) : 0;
    if (!Doubles(&X_WF, 12, "X_WF") || !Doubles(&p_FS, 3 * n, "p_FS") ||
        !Doubles(&u_F, 3 * n * k, "u_F") || !Doubles(&z_F, 3 * n, "z_F") ||
        !Doubles(&frames, m, "frames") || !Doubles(&X_FG, 12 * m, "X_FG") ||
        !Doubles(&sizes, 3 * m, "sizes") || !Doubles(&rho, m, "rho") ||
        !Doubles(&X_WM, 12 * f, "X_WM"))
        goto done;
    const double *X = X_WF.buf, *pF = p_FS.buf, *uF = u_F.buf, *zF = z_F.buf;
    const double *kind = kinds.buf, *frame = frames.buf, *XFG = X_FG.buf, *size = sizes.buf;
    const double *ball = rho.buf, *XWM = X_WM.buf;
    double *out = best.buf;
    double *X_WG = PyMem_Malloc((size_t)(12 * (m > 0 ? m : 1)) * sizeof(double));
    if (X_WG == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t j = 0; j < m; ++j) {
        int index = (int)frame[j];
        if (index < -1 || index >= f) {
            PyMem_Free(X_WG);
            PyErr_Format(PyExc_ValueError, "frames[%zd] = %d: no such frame", j, index);
            goto done;
        }
        if (index < 0)
            memcpy(X_WG + 12 * j, XFG + 12 * j, 12 * sizeof(double));
        else
            Compose(XWM + 12 * index, XFG + 12 * j, X_WG + 12 * j);
    }
    double *u_W = PyMem_Malloc((size_t)(3 * (k > 0 ? k : 1)) * sizeof(double));
    struct Candidate *order = PyMem_Malloc((size_t)(m > 0 ? m : 1) * sizeof(struct Candidate));
    if (u_W == NULL || order == NULL) {
        PyMem_Free(X_WG);
        PyMem_Free(u_W);
    PyMem_Free(order);
        PyMem_Free(order);
        PyErr_NoMemory();
        goto done;
    }
    double cos_half = cos(half_angle), sin_half = sin(half_angle);
    for (Py_ssize_t i = 0; i < n; ++i) {
        double p[3], z[3];
        Rotate(X, pF + 3 * i, p);
        for (int c = 0; c < 3; ++c) p[c] += X[4 * c + 3];
        Rotate(X, zF + 3 * i, z);
        for (Py_ssize_t q = 0; q < k; ++q) Rotate(X, uF + 3 * (i * k + q), u_W + 3 * q);
        /* The shapes whose ball meets the sensor's cone truncated at reach, nearest ball
         * first: none past the nearest hit so far can beat it (no point of a ball is nearer
         * than |d| - r). */
        Py_ssize_t count = 0;
        for (Py_ssize_t j = 0; j < m; ++j) {
            const double *G = X_WG + 12 * j;
            double d[3] = {G[3] - p[0], G[7] - p[1], G[11] - p[2]};  /* p_WG - p_WS */
            double r = ball[j], near = -INFINITY;
            if (!isinf(r)) {
                /* The ball (centre along the axis x, off it y) against the cone. */
                double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                double x = d[0] * z[0] + d[1] * z[1] + d[2] * z[2];
                double y2 = d2 - x * x;
                double y = sqrt(y2 > 0.0 ? y2 : 0.0);
                if (!(y * cos_half - x * sin_half <= r && x >= -r && x <= reach + r)) continue;
                near = sqrt(d2) - r;
            }
            Py_ssize_t at = count++;  /* insertion by near */
            while (at > 0 && order[at - 1].near > near) {
                order[at] = order[at - 1];
                --at;
            }
            order[at].near = near;
            order[at].shape = j;
        }
        double nearest = INFINITY;
        for (Py_ssize_t rank = 0; rank < count && order[rank].near <= nearest; ++rank) {
            Py_ssize_t j = order[rank].shape;
            const double *G = X_WG + 12 * j;
            double d[3] = {G[3] - p[0], G[7] - p[1], G[11] - p[2]};
            double o[3];  /* p_WS - p_WG in G */
            for (int c = 0; c < 3; ++c) o[c] = -(G[c] * d[0] + G[4 + c] * d[1] + G[8 + c] * d[2]);
            for (Py_ssize_t q = 0; q < k; ++q) {
                const double *uw = u_W + 3 * q;
                double u[3];
                for (int c = 0; c < 3; ++c) u[c] = G[c] * uw[0] + G[4 + c] * uw[1] + G[8 + c] * uw[2];
                double ou = -(d[0] * uw[0] + d[1] * uw[1] + d[2] * uw[2]);
                double t = FirstHit((int)kind[j], o, u, ou, size + 3 * j);
                if (t < nearest) nearest = t;
            }
        }
        out[i] = nearest <= reach ? nearest : INFINITY;
    }
    PyMem_Free(u_W);
    PyMem_Free(order);
    PyMem_Free(X_WG);
    result = Py_None;
    Py_INCREF(result);
done:
    for (size_t b = 0; b < sizeof(all) / sizeof(all[0]); ++b) PyBuffer_Release(all[b]);
    return result;
}

static PyMethodDef kMethods[] = {
    {"CastCones", CastCones, METH_VARARGS, "Nearest hits of cone rays (see the module source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kModule = {PyModuleDef_HEAD_INIT, "_cone_casting",
                                     "Compiled kernel of primitive_ray_casting.", -1, kMethods};

PyMODINIT_FUNC PyInit__cone_casting(void) { return PyModule_Create(&kModule); }
