/* time_event: an integrator of a rate that switches at a time event,
 *     x' = r,  r = 1 before the time T and -1 from T on,
 * r being a discrete state changed only at the time event that the model schedules
 * (nextEventTime = T in model exchange; co-simulation stops its integration at T).
 * Closed form: x = t for t < T, x = 2 T - t after. */
#include "../model.h"

enum { T_SWITCH, X, R, DER_X, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 1, model_n_indicators = 0;
const char model_kinds[] = "pccc";
const unsigned model_state_vr[] = {X}, model_derivative_vr[] = {DER_X};

void model_start(ModelData *m) { m->r[T_SWITCH] = 0.5; }

void model_initialize(ModelData *m) {
    m->r[X] = 0.0;
    m->r[R] = time_reached(m->time, m->r[T_SWITCH]) ? -1.0 : 1.0;
}

void model_compute(ModelData *m) { m->r[DER_X] = m->r[R]; }

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) {
    if (time_reached(m->time, m->r[T_SWITCH])) {
        m->r[R] = -1.0;
    } else {
        m->r[R] = 1.0;
        *next_time = m->r[T_SWITCH];
    }
    return 0;
}
