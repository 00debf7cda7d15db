/* feedthrough: a static gain with an offset, y = g u + c, no states; y depends
 * directly on u.  Two instances (g1, c1) and (g2, c2) connected y1 -> u2, y2 -> u1
 * form an algebraic loop whose solution is y1 = (g1 c2 + c1) / (1 - g1 g2),
 * y2 = g2 y1 + c2. */
#include "../model.h"

enum { GAIN, OFFSET, U, Y, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 0, model_n_indicators = 0;
const char model_kinds[] = "ppic";
const unsigned model_state_vr[] = {0}, model_derivative_vr[] = {0};  /* none */

void model_start(ModelData *m) { m->r[GAIN] = 0.5; m->r[OFFSET] = 1.0; m->r[U] = 0.0; }

void model_initialize(ModelData *m) { (void)m; }

void model_compute(ModelData *m) { m->r[Y] = m->r[GAIN] * m->r[U] + m->r[OFFSET]; }

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
