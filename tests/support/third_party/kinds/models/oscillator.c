/* oscillator: a damped mass-spring oscillator driven by an external force,
 *     m a = F - k x - d v,   x' = v,  v' = a,
 * with the variables named as dsim's ports: input P.f_x = F (N), outputs P.u_x = x
 * (m), P.v_x = v (m/s) and P.a_x = a (m/s2, depends directly on P.f_x).
 * Closed form (F = 0, d = 0): x = x0 cos(w t) + v0/w sin(w t), w = sqrt(k/m);
 * with 0 < d < 2 sqrt(k m), s = d/(2m), wd = sqrt(k/m - s^2):
 *     x = exp(-s t) (x0 cos(wd t) + (v0 + s x0)/wd sin(wd t)). */
#include "../model.h"

enum { M, K, D, X0, V0, F, X, V, A, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 2, model_n_indicators = 0;
const char model_kinds[] = "pppppiccc";
const unsigned model_state_vr[] = {X, V}, model_derivative_vr[] = {V, A};

void model_start(ModelData *m) {
    m->r[M] = 1.0; m->r[K] = 1.0; m->r[D] = 0.0; m->r[X0] = 1.0; m->r[V0] = 0.0;
    m->r[F] = 0.0;
}

void model_initialize(ModelData *m) { m->r[X] = m->r[X0]; m->r[V] = m->r[V0]; }

void model_compute(ModelData *m) {
    double *r = m->r;
    r[A] = (r[F] - r[K] * r[X] - r[D] * r[V]) / r[M];
}

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
