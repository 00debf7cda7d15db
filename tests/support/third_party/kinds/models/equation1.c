/* equation1: half of OMSimulator's equationPair test, 2 x1^2 + 5 x2 = 42 solved for
 * its output, x2 = (42 - 2 x1^2) / 5, from its input x1.  With equation2
 * (x1 - 6 x2 = 4, x1 = 4 + 6 x2) connected x2 -> x2, x1 -> x1 it forms a nonlinear
 * algebraic loop whose root is 2.4 x1^2 + x1 - 54.4 = 0, x1 > 0:
 * x1 = (-1 + sqrt(523.24)) / 4.8, x2 = (x1 - 4) / 6. */
#include "../model.h"

enum { X1, X2, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 0, model_n_indicators = 0;
const char model_kinds[] = "ic";
const unsigned model_state_vr[] = {0}, model_derivative_vr[] = {0};  /* none */

void model_start(ModelData *m) { m->r[X1] = 4.0; }

void model_initialize(ModelData *m) { (void)m; }

void model_compute(ModelData *m) { m->r[X2] = (42.0 - 2.0 * m->r[X1] * m->r[X1]) / 5.0; }

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
