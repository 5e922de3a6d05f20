/* The range model and fits of hose_range.c (hose_range_model.c), plain C: their
 * constants, the model and the functions the module's entry points call. */
#ifndef GUIDEDARM_CSRC_HOSE_RANGE_H_
#define GUIDEDARM_CSRC_HOSE_RANGE_H_

#define SENSORS 6
#define MAX_RIM 64
/* As hose_range_model: the finite-difference step (m) and the iterations of the fits. */
#define STEP 1e-5
#define CENTRE_ITERATIONS 8
#define RADIUS_ITERATIONS 10
#define MAX_STARTS 8


typedef struct {
    const double *e, *z; /* emitters, axes (SENSORS x 3) */
    double radius, cos_half, sin_half;
    const double *rim; /* rim_count (cos phi, sin phi) pairs */
    int rim_count;
    /* The radius fit's ranges past a cone's rim (hose_range_model.RadiusFit): the range
     * grows by miss_slope per m the hose misses the cone, up to max_miss (m). */
    double miss_slope, max_miss;
} Model;

int PlaneRangeOf(const Model *m, int k, const double *c, double r, double *out);
int CylinderRangeOf(const Model *m, int k, const double *c, const double *a, double r,
                    double *out);
int RangeOf(const Model *m, int k, const double *c, const double *axis, double r,
            double *out);
double Distance(const double *a, const double *b);
void LeastSquares(int rows, int n, double *J, const double *r, double *x);
void LeastSquares2(int rows, double *J, const double *r, double *step);
void RefineOf(const Model *m, const double *c, const double *ranges, const int *sensors,
              int count, const double *axis, double max_shift, double *x);
int RadiusFitFrom(const Model *m, const double *c, double radius, const double *ranges,
                  const int *sensors, int count, const double *axis, int min_sensors,
                  double *x, double *fitted, double *misfit);

#endif  // GUIDEDARM_CSRC_HOSE_RANGE_H_
