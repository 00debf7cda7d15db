/* bouncing_ball: a ball falling from height h0 onto the ground and bouncing back,
 *     h' = v,  v' = der(v) = -g,  event indicator h;
 * when h reaches 0 going down: v := -e v, h := 0 (a rebound slower than v_min leaves
 * the ball at rest on the ground: h = v = 0 for ever, which ends the Zeno cascade
 * of bounces at t = t1 + 2 e v1 / (g (1 - e))).
 * Closed form: first impact at t1 = sqrt(2 h0 / g) with speed v1 = g t1; the n-th
 * flight after it lasts 2 e^n v1 / g. */
#include "../model.h"

enum { G, E, H0, V_MIN, H, V, DER_V, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 2, model_n_indicators = 1;
const char model_kinds[] = "ppppccc";
const unsigned model_state_vr[] = {H, V}, model_derivative_vr[] = {V, DER_V};

#define AT_REST 1

void model_start(ModelData *m) {
    m->r[G] = 9.81; m->r[E] = 0.7; m->r[H0] = 1.0; m->r[V_MIN] = 0.1;
}

void model_initialize(ModelData *m) { m->r[H] = m->r[H0]; m->r[V] = 0.0; m->flags = 0; }

void model_compute(ModelData *m) { m->r[DER_V] = m->flags == AT_REST ? 0.0 : -m->r[G]; }

void model_indicators(const ModelData *m, double z[]) { z[0] = m->r[H]; }

int model_event(ModelData *m, double *next_time) {
    (void)next_time;
    if (m->flags == AT_REST || m->r[H] > 0.0 || m->r[V] >= 0.0) return 0;
    m->r[H] = 0.0;
    m->r[V] = -m->r[E] * m->r[V];
    if (m->r[V] < m->r[V_MIN]) { m->r[V] = 0.0; m->flags = AT_REST; }
    return 1;
}
