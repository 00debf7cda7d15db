/* mass2: the second half of the two-mass oscillator benchmark of co-simulation,
 * the second mass and the coupling spring-damper to the first mass:
 *     Fc = kc (x2 - x1) + dc (v2 - v1),   m2 a2 = -k2 x2 - d2 v2 - Fc,
 * inputs x1 (m), v1 (m/s); outputs F = Fc (N, the force on mass 1, depends directly
 * on x1 and v1), x2 (m), v2 (m/s), a2 (m/s2).
 * Closed form alone with a constant x1 (v1 = 0, x2_0 = v2_0 = 0, dampers 0):
 *     x2 = kc x1 / (k2 + kc) (1 - cos(w t)),  w = sqrt((k2 + kc)/m2).
 * Coupled with mass1 (mass1.F = mass2.F, mass2.x1 = mass1.x1, mass2.v1 = mass1.v1) the
 * states (x1, v1, x2, v2) follow the linear system s' = A s with
 *     x1'' = (-(k1 + kc) x1 - (d1 + dc) v1 + kc x2 + dc v2) / m1
 *     x2'' = (kc x1 + dc v1 - (k2 + kc) x2 - (d2 + dc) v2) / m2,  s(t) = expm(A t) s0. */
#include "../model.h"

enum { M2, K2, D2, KC, DC, X2_0, V2_0, X1, V1, F, X2, V2, A2, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 2, model_n_indicators = 0;
const char model_kinds[] = "pppppppiicccc";
const unsigned model_state_vr[] = {X2, V2}, model_derivative_vr[] = {V2, A2};

void model_start(ModelData *m) {
    m->r[M2] = 1.0; m->r[K2] = 10.0; m->r[D2] = 0.0; m->r[KC] = 100.0; m->r[DC] = 0.0;
    m->r[X2_0] = 0.0; m->r[V2_0] = 0.0; m->r[X1] = 0.0; m->r[V1] = 0.0;
}

void model_initialize(ModelData *m) { m->r[X2] = m->r[X2_0]; m->r[V2] = m->r[V2_0]; }

void model_compute(ModelData *m) {
    double *r = m->r;
    r[F] = r[KC] * (r[X2] - r[X1]) + r[DC] * (r[V2] - r[V1]);
    r[A2] = (-r[K2] * r[X2] - r[D2] * r[V2] - r[F]) / r[M2];
}

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
