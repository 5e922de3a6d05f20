/* The range model and the Gauss-Newton fits behind csrc/hose_range.c (see its comment and
 * guidedarm.systems.tof.hose_range_model's docstrings): plain C, no Python. */

#include "hose_range.h"

#include <float.h>
#include <math.h>

/* Sensor k's view of a hose perpendicular to the detection plane centred at c: 0 when c
 * is behind the emitter; 1 when c is inside the cone (*distance from the emitter); 2
 * otherwise, with the distance t along the cone's rim ray nearest c of c's foot on it and
 * h2, c's squared distance from that ray. */
static int PlaneViewOf(const Model *m, int k, const double *c, double *distance, double *t,
                       double *h2) {
    const double *e = m->e + 3 * k, *z = m->z + 3 * k;
    double d0 = c[0] - e[0], d1 = c[1] - e[1], d2 = c[2] - e[2];
    *distance = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    double along = d0 * z[0] + d1 * z[1] + d2 * z[2];
    if (along <= 0) return 0;
    if (along >= *distance * m->cos_half) return 1;
    double s0 = d0 - along * z[0], s1 = d1 - along * z[1], s2 = d2 - along * z[2];
    double norm = sqrt(s0 * s0 + s1 * s1 + s2 * s2);
    double ch = m->cos_half, sh = m->sin_half;
    *t = d0 * (ch * z[0] + sh * s0 / norm) + d1 * (ch * z[1] + sh * s1 / norm) +
         d2 * (ch * z[2] + sh * s2 / norm);
    *h2 = *distance * *distance - *t * *t;
    return 2;
}

/* PlaneRange: 1 and *out, or 0 when the cone misses the hose. */
int PlaneRangeOf(const Model *m, int k, const double *c, double r, double *out) {
    double distance, t, h2;
    int view = PlaneViewOf(m, k, c, &distance, &t, &h2);
    if (view == 0) return 0;
    if (view == 1) {
        *out = distance - r;
        return 1;
    }
    double r2 = r * r;
    if (h2 > r2) return 0;
    *out = t - sqrt(r2 - h2);
    return 1;
}

/* Sensor k's view of the cylinder of radius r, unit axis a through c: the emitter's
 * distance from the axis and, in the frame of the cone's rim (z the line of sight, x toward
 * the axis, y = z x x), the axis and the emitter's offset d from it projected on z, x, y
 * and d on the axis. */
typedef struct {
    double distance, za, xa, ya, zd, xd, yd, ad;
} CylinderView;

/* 0 when the emitter is inside the cylinder or the axis lies behind it; 1 when the nearest
 * point of the axis is inside the cone (view->distance set); 2 with the whole view. */
static int CylinderViewOf(const Model *m, int k, const double *c, const double *a, double r,
                          CylinderView *view) {
    const double *e = m->e + 3 * k, *z = m->z + 3 * k;
    double f0 = e[0] - c[0], f1 = e[1] - c[1], f2 = e[2] - c[2];
    double along = f0 * a[0] + f1 * a[1] + f2 * a[2];
    double d0 = f0 - a[0] * along, d1 = f1 - a[1] * along, d2 = f2 - a[2] * along;
    double distance = sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    view->distance = distance;
    if (distance <= r) return 0;
    double n0 = -d0 / distance, n1 = -d1 / distance, n2 = -d2 / distance;
    double nz = n0 * z[0] + n1 * z[1] + n2 * z[2];
    if (nz >= m->cos_half) return 1;
    double s0 = n0 - nz * z[0], s1 = n1 - nz * z[1], s2 = n2 - nz * z[2];
    double norm = sqrt(s0 * s0 + s1 * s1 + s2 * s2);
    if (norm < 1e-12 || nz <= 0) return 0;
    double x0 = s0 / norm, x1 = s1 / norm, x2 = s2 / norm;
    double y0 = z[1] * x2 - z[2] * x1, y1 = z[2] * x0 - z[0] * x2, y2 = z[0] * x1 - z[1] * x0;
    view->za = z[0] * a[0] + z[1] * a[1] + z[2] * a[2];
    view->xa = x0 * a[0] + x1 * a[1] + x2 * a[2];
    view->ya = y0 * a[0] + y1 * a[1] + y2 * a[2];
    view->zd = z[0] * d0 + z[1] * d1 + z[2] * d2;
    view->xd = x0 * d0 + x1 * d1 + x2 * d2;
    view->yd = y0 * d0 + y1 * d1 + y2 * d2;
    view->ad = a[0] * d0 + a[1] * d1 + a[2] * d2;
    return 2;
}

/* CylinderRange: 1 and *out, or 0 when the cone misses the cylinder. */
int CylinderRangeOf(const Model *m, int k, const double *c, const double *a, double r,
                    double *out) {
    CylinderView g;
    int view = CylinderViewOf(m, k, c, a, r, &g);
    if (view == 0) return 0;
    if (view == 1) {
        *out = g.distance - r;
        return 1;
    }
    double cos_half = m->cos_half, distance = g.distance;
    double za = g.za, xa = g.xa, ya = g.ya, zd = g.zd, xd = g.xd, yd = g.yd, ad = g.ad;
    double wa0 = cos_half * za, wd0 = cos_half * zd;
    double gap = distance * distance - r * r;
    double t[MAX_RIM];
    int count = m->rim_count, best_at = -1;
    for (int i = 0; i < count; ++i) {
        double cos_phi = m->rim[2 * i], sin_phi = m->rim[2 * i + 1];
        double wa = wa0 + cos_phi * xa + sin_phi * ya;
        double b = wd0 + cos_phi * xd + sin_phi * yd - wa * ad;
        double aa = 1.0 - wa * wa;
        double disc = b * b - aa * gap;
        t[i] = disc >= 0 && b < 0 ? (-b - sqrt(disc)) / (aa < 1e-12 ? 1e-12 : aa) : INFINITY;
        if (best_at < 0 || t[i] < t[best_at]) best_at = i; /* the first least, as min() */
    }
    if (best_at < 0) return 0;
    double best = t[best_at];
    if (best == INFINITY) return 0;
    int i = best_at;
    if (0 < i && i < count - 1 && t[i - 1] < INFINITY && t[i + 1] < INFINITY) {
        double curvature = t[i - 1] - 2 * best + t[i + 1];
        if (curvature > 0) {
            double slope = (t[i + 1] - t[i - 1]) / 2;
            *out = best - slope * slope / (2 * curvature);
            return 1;
        }
    }
    *out = best;
    return 1;
}

/* The range sensor k reads for a hose centred at c: along axis, or perpendicular (NULL). */
int RangeOf(const Model *m, int k, const double *c, const double *axis, double r,
            double *out) {
    return axis ? CylinderRangeOf(m, k, c, axis, r, out) : PlaneRangeOf(m, k, c, r, out);
}

double Distance(const double *a, const double *b) {
    double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}

/* The minimum-norm least-squares solution x (n) of J x = r, J (rows x n, row-major, n <= 3,
 * overwritten), as numpy.linalg.lstsq with rcond=None: singular values at most
 * eps max(rows, n) times the largest count as zero. One-sided Jacobi SVD: J's columns are
 * rotated until orthogonal (J V = U S), then x = sum over kept j of V_j (J V)_j . r / s_j^2. */
void LeastSquares(int rows, int n, double *J, const double *r, double *x) {
    double V[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (int p = 0; p < n; ++p) {
            for (int q = p + 1; q < n; ++q) {
                double alpha = 0, beta = 0, gamma = 0;
                for (int i = 0; i < rows; ++i) {
                    double jp = J[i * n + p], jq = J[i * n + q];
                    alpha += jp * jp;
                    beta += jq * jq;
                    gamma += jp * jq;
                }
                if (gamma == 0 || fabs(gamma) <= DBL_EPSILON * sqrt(alpha * beta)) continue;
                rotated = 1;
                double zeta = (beta - alpha) / (2 * gamma);
                double t = (zeta >= 0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1 + zeta * zeta));
                double cs = 1 / sqrt(1 + t * t), sn = cs * t;
                for (int i = 0; i < rows; ++i) {
                    double jp = J[i * n + p], jq = J[i * n + q];
                    J[i * n + p] = cs * jp - sn * jq;
                    J[i * n + q] = sn * jp + cs * jq;
                }
                for (int i = 0; i < n; ++i) {
                    double vp = V[i][p], vq = V[i][q];
                    V[i][p] = cs * vp - sn * vq;
                    V[i][q] = sn * vp + cs * vq;
                }
            }
        }
        if (!rotated) break;
    }
    double s2[3], largest = 0;
    for (int j = 0; j < n; ++j) {
        s2[j] = 0;
        for (int i = 0; i < rows; ++i) s2[j] += J[i * n + j] * J[i * n + j];
        if (s2[j] > largest) largest = s2[j];
    }
    double cutoff = DBL_EPSILON * (rows > n ? rows : n);
    cutoff = cutoff * cutoff * largest; /* on s^2 */
    for (int i = 0; i < n; ++i) x[i] = 0;
    for (int j = 0; j < n; ++j) {
        if (!(s2[j] > cutoff)) continue;
        double projection = 0;
        for (int i = 0; i < rows; ++i) projection += J[i * n + j] * r[i];
        for (int i = 0; i < n; ++i) x[i] += V[i][j] * projection / s2[j];
    }
}

/* The least-squares solution of J s = r for J with two columns, by the normal equations;
 * LeastSquares' (the minimum-norm one) when J is nearly rank-deficient. */
void LeastSquares2(int rows, double *J, const double *r, double *step) {
    double s00 = 0, s01 = 0, s11 = 0, g0 = 0, g1 = 0;
    for (int i = 0; i < rows; ++i) {
        double j0 = J[2 * i], j1 = J[2 * i + 1];
        s00 += j0 * j0;
        s01 += j0 * j1;
        s11 += j1 * j1;
        g0 += j0 * r[i];
        g1 += j1 * r[i];
    }
    double det = s00 * s11 - s01 * s01;
    if (det <= 1e-10 * s00 * s11) {
        LeastSquares(rows, 2, J, r, step);
        return;
    }
    step[0] = (s11 * g0 - s01 * g1) / det;
    step[1] = (s00 * g1 - s01 * g0) / det;
}

/* HoseRangeModel.Refine into x (3). */
void RefineOf(const Model *m, const double *c, const double *ranges, const int *sensors,
              int count, const double *axis, double max_shift, double *x) {
    int needed = axis ? 2 : 3;
    x[0] = c[0], x[1] = c[1], x[2] = c[2];
    if (count < needed) return;
    const double *u = m->z, *v = m->z + 9; /* sensors 1 and 4's lines of sight */
    double y[3] = {c[0], c[1], c[2]}, h = STEP;
    for (int iteration = 0; iteration < CENTRE_ITERATIONS; ++iteration) {
        double moved_u[3], moved_v[3], J[2 * SENSORS], residuals[SENSORS];
        for (int i = 0; i < 3; ++i) {
            moved_u[i] = y[i] + h * u[i];
            moved_v[i] = y[i] + h * v[i];
        }
        int rows = 0;
        for (int s = 0; s < count; ++s) {
            int k = sensors[s];
            double p, q_u, q_v;
            if (!RangeOf(m, k, y, axis, m->radius, &p) ||
                !RangeOf(m, k, moved_u, axis, m->radius, &q_u) ||
                !RangeOf(m, k, moved_v, axis, m->radius, &q_v))
                continue;
            J[2 * rows] = (q_u - p) / h;
            J[2 * rows + 1] = (q_v - p) / h;
            residuals[rows++] = ranges[k] - p;
        }
        if (rows < needed) return;
        double step[2];
        LeastSquares2(rows, J, residuals, step);
        for (int i = 0; i < 3; ++i) y[i] += step[0] * u[i] + step[1] * v[i];
        if (sqrt(step[0] * step[0] + step[1] * step[1]) < 1e-6) break;
    }
    if (Distance(y, c) <= max_shift) x[0] = y[0], x[1] = y[1], x[2] = y[2];
}

/* The range sensor k's rim reads for a hose of radius r centred at c (along axis, or
 * perpendicular when NULL) that its cone just misses, extended past the rim: the range
 * along the rim ray of the hose's closest approach plus MISS_SLOPE times the gap left
 * (m), continuous with RangeOf's where the rim ray grazes the hose, and the gap in *miss.
 * 0 when the gap passes max_miss, the hose is behind the emitter or the emitter inside
 * it. */
static int MissRangeOf(const Model *m, int k, const double *c, const double *axis, double r,
                       double *out, double *miss) {
    if (!axis) {
        double distance, t, h2;
        if (PlaneViewOf(m, k, c, &distance, &t, &h2) != 2) return 0;
        double gap = sqrt(h2 > 0 ? h2 : 0) - r;
        if (gap > m->max_miss) return 0;
        *out = t + m->miss_slope * gap;
        *miss = gap;
        return 1;
    }
    CylinderView g;
    if (CylinderViewOf(m, k, c, axis, r, &g) != 2) return 0;
    double best = INFINITY, best_gap = 0;
    for (int i = 0; i < m->rim_count; ++i) {
        double cos_phi = m->rim[2 * i], sin_phi = m->rim[2 * i + 1];
        double wa = m->cos_half * g.za + cos_phi * g.xa + sin_phi * g.ya;
        double b = m->cos_half * g.zd + cos_phi * g.xd + sin_phi * g.yd - wa * g.ad;
        double aa = 1.0 - wa * wa;
        /* The ray's closest approach to the axis, not behind the emitter. */
        double t = b < 0 && aa > 1e-12 ? -b / aa : 0.0;
        double closest2 = g.distance * g.distance + 2 * b * t + aa * t * t;
        double gap = sqrt(closest2 > 0 ? closest2 : 0) - r;
        double value = t + m->miss_slope * gap;
        if (gap <= m->max_miss && value < best) best = value, best_gap = gap;
    }
    *out = best;
    *miss = best_gap;
    return best < INFINITY;
}

/* RangeOf where the cone meets the hose (*miss 0), MissRangeOf where it misses it. */
static int ExtendedRangeOf(const Model *m, int k, const double *c, const double *axis,
                           double r, double *out, double *miss) {
    *miss = 0;
    return RangeOf(m, k, c, axis, r, out) || MissRangeOf(m, k, c, axis, r, out, miss);
}

/* RadiusFit from one start radius: 1 with the centre x, radius and RMS misfit, or 0. */
int RadiusFitFrom(const Model *m, const double *c, double radius, const double *ranges,
                  const int *sensors, int count, const double *axis, int min_sensors,
                  double *x, double *fitted, double *misfit) {
    const double *u = m->z, *v = m->z + 9;
    double h = STEP, residuals[SENSORS], misses[SENSORS];
    int rows = 0;
    /* A hose thicker by e reads as one e nearer along both facing sensors' lines of
     * sight: the start's centre moves e along each. */
    double e = radius - m->radius;
    for (int i = 0; i < 3; ++i) x[i] = c[i] + e * u[i] + e * v[i];
    for (int iteration = 0; iteration < RADIUS_ITERATIONS; ++iteration) {
        double pu[3], pv[3], J[3 * SENSORS];
        for (int i = 0; i < 3; ++i) {
            pu[i] = x[i] + h * u[i];
            pv[i] = x[i] + h * v[i];
        }
        rows = 0;
        for (int s = 0; s < count; ++s) {
            int k = sensors[s];
            double at, at_u, at_v, grown, miss, unused;
            if (!ExtendedRangeOf(m, k, x, axis, radius, &at, &miss) ||
                !ExtendedRangeOf(m, k, pu, axis, radius, &at_u, &unused) ||
                !ExtendedRangeOf(m, k, pv, axis, radius, &at_v, &unused) ||
                !ExtendedRangeOf(m, k, x, axis, radius + h, &grown, &unused))
                continue;
            misses[rows] = miss;
            J[3 * rows] = (at_u - at) / h;
            J[3 * rows + 1] = (at_v - at) / h;
            J[3 * rows + 2] = (grown - at) / h;
            residuals[rows++] = ranges[k] - at;
        }
        if (rows < min_sensors) return 0;
        double step[3];
        LeastSquares(rows, 3, J, residuals, step);
        for (int i = 0; i < 3; ++i) x[i] = x[i] + step[0] * u[i] + step[1] * v[i];
        radius += step[2];
        if (!(m->radius / 2 <= radius && radius <= 2 * m->radius)) return 0;
        if (sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]) < 1e-6) break;
    }
    /* A row its cone still misses counts its gap too: the sensor saw the hose there. */
    double squares = 0;
    for (int i = 0; i < rows; ++i)
        squares += residuals[i] * residuals[i] + misses[i] * misses[i];
    *fitted = radius;
    *misfit = sqrt(squares / rows);
    return 1;
}

