/* The paper model's RK4 step in plain C: the speed anchor of bench_model.py.

   The Fig. 7 listing as model/paper.py writes it (eq. 12, 14, 16 with its factor 1/2; see
   docs/model.md "Mechanics (paper mode)"), classical RK4 at a fixed step, the valve command
   held. Nothing else: no substeps, no checks. bench_model.py compiles it with the machine's
   C compiler, runs it on the constants of the same parameter set as the compiled Python
   step, and checks that both end in the same state before it compares their speed.

   usage: paper_rk4 U DT STEPS REPEATS Q1 V P1 A B H INERTIA WEIGHT_COEFF S1 V1 E K_ORIFICE
                    P_N COULOMB VISCOUS SPRING F_EXTERNAL
   prints: the final q1 v p1 E_supply E_loss, then the best ns per step over REPEATS runs */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

typedef struct {
    double a, b, h, inertia, weight_coeff, s1, v1, e, k_orifice, p_n, coulomb, viscous, spring, f_external;
} Constants;

static void derivative(const Constants *c, double u, const double y[5], double dy[5]) {
    double q1 = y[0], v = y[1], p1 = y[2];
    double opening = 0.5 * (u + fabs(u));                           /* the valve only lifts */
    double dp = c->p_n - p1;
    double flow = c->k_orifice * opening * copysign(sqrt(fabs(dp)), dp); /* eq. 14 */
    double dp1 = c->e / c->v1 * (flow - c->s1 * v);                 /* eq. 12, constant V1 */
    double x = (c->a * c->a + c->b * c->b - q1 * q1) / (2.0 * c->a * c->b);
    double s2 = 1.0 - x * x, ab = c->a * c->b;
    double theta = acos(c->h / c->b) + acos(x);
    double weight = c->weight_coeff * sin(theta) / (ab * sqrt(s2));
    double centripetal = (1.0 - x * q1 * q1 / (ab * s2)) * c->inertia * q1 / (ab * ab * s2) * v * v;
    double friction = c->coulomb + c->viscous * v;
    double force = p1 * c->s1 + c->f_external;
    dy[0] = v;
    dy[1] = ab * ab * s2 / (2.0 * c->inertia * q1 * q1)
            * (force - friction - (c->spring + weight) * q1 - centripetal); /* eq. 16 as in Fig. 7 */
    dy[2] = dp1;
    dy[3] = c->p_n * flow;
    dy[4] = dp * flow;
}

static void rk4_step(const Constants *c, double u, double y[5], double h) {
    double k1[5], k2[5], k3[5], k4[5], s[5];
    derivative(c, u, y, k1);
    for (int i = 0; i < 5; i++) s[i] = y[i] + 0.5 * h * k1[i];
    derivative(c, u, s, k2);
    for (int i = 0; i < 5; i++) s[i] = y[i] + 0.5 * h * k2[i];
    derivative(c, u, s, k3);
    for (int i = 0; i < 5; i++) s[i] = y[i] + h * k3[i];
    derivative(c, u, s, k4);
    for (int i = 0; i < 5; i++) y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

int main(int argc, char **argv) {
    if (argc != 22) {
        fprintf(stderr, "paper_rk4: expected 21 arguments, got %d (see the source's usage)\n", argc - 1);
        return 2;
    }
    double u = atof(argv[1]), dt = atof(argv[2]);
    long steps = atol(argv[3]), repeats = atol(argv[4]);
    double y0[5] = {atof(argv[5]), atof(argv[6]), atof(argv[7]), 0.0, 0.0};
    Constants c = {atof(argv[8]),  atof(argv[9]),  atof(argv[10]), atof(argv[11]), atof(argv[12]),
                   atof(argv[13]), atof(argv[14]), atof(argv[15]), atof(argv[16]), atof(argv[17]),
                   atof(argv[18]), atof(argv[19]), atof(argv[20]), atof(argv[21])};
    double y[5], best = INFINITY;
    for (long r = 0; r < repeats; r++) {
        for (int i = 0; i < 5; i++) y[i] = y0[i];
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (long n = 0; n < steps; n++) rk4_step(&c, u, y, dt);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        double ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / (double)steps;
        if (ns < best) best = ns;
    }
    printf("%.17g %.17g %.17g %.17g %.17g\n%.3f\n", y[0], y[1], y[2], y[3], y[4], best);
    return 0;
}
