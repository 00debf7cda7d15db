/* mass1: the first half of the two-mass oscillator benchmark of co-simulation,
 *     m1 a1 = F - k1 x1 - d1 v1,   x1' = v1,  v1' = a1,
 * driven by the coupling force F (N, an input) that mass2 computes; outputs x1 (m),
 * v1 (m/s) and a1 (m/s2, depends directly on F).
 * Closed form alone (F = 0, d1 = 0): x1 = x1_0 cos(w t) + v1_0/w sin(w t),
 * w = sqrt(k1/m1); coupled to mass2 the four states follow the linear system of
 * mass2.c's comment. */
#include "../model.h"

enum { M1, K1, D1, X1_0, V1_0, F, X1, V1, A1, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 2, model_n_indicators = 0;
const char model_kinds[] = "pppppiccc";
const unsigned model_state_vr[] = {X1, V1}, model_derivative_vr[] = {V1, A1};

void model_start(ModelData *m) {
    m->r[M1] = 1.0; m->r[K1] = 10.0; m->r[D1] = 0.0; m->r[X1_0] = 0.1; m->r[V1_0] = 0.0;
    m->r[F] = 0.0;
}

void model_initialize(ModelData *m) { m->r[X1] = m->r[X1_0]; m->r[V1] = m->r[V1_0]; }

void model_compute(ModelData *m) {
    double *r = m->r;
    r[A1] = (r[F] - r[K1] * r[X1] - r[D1] * r[V1]) / r[M1];
}

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
