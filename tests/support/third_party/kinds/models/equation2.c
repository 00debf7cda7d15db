/* equation2: the other half of OMSimulator's equationPair test, x1 - 6 x2 = 4 solved
 * for its output, x1 = 4 + 6 x2, from its input x2 (see equation1.c). */
#include "../model.h"

#ifndef X2_START  /* the start value of the input x2 (the modelDescription.xml's) */
#define X2_START 8.4
#endif

enum { X2, X1, N_VARS };

const int model_n_vars = N_VARS, model_n_states = 0, model_n_indicators = 0;
const char model_kinds[] = "ic";
const unsigned model_state_vr[] = {0}, model_derivative_vr[] = {0};  /* none */

void model_start(ModelData *m) { m->r[X2] = X2_START; }

void model_initialize(ModelData *m) { (void)m; }

void model_compute(ModelData *m) { m->r[X1] = 4.0 + 6.0 * m->r[X2]; }

void model_indicators(const ModelData *m, double z[]) { (void)m; (void)z; }

int model_event(ModelData *m, double *next_time) { (void)m; (void)next_time; return 0; }
