/* The interface between a model (models/<name>.c) and the FMI skeletons of this folder
 * (fmi1cs.c, fmi2.c, fmi3.c, all built on core.c).
 *
 * A model has only Real (Float64) variables, kept in one array indexed by value
 * reference.  Its continuous states are some of these variables, and so are their
 * derivatives (model_state_vr[i] has the derivative model_derivative_vr[i]; a state
 * may be the derivative of another, as a velocity is the derivative of a position).
 * Discrete states (a piecewise constant rate, a ball at rest) change only in
 * model_event; the skeletons call it at the start (after initialization), at a state
 * event (an event indicator changed sign) and at a time event (the time it asked for).
 */
#ifndef KINDS_MODEL_H
#define KINDS_MODEL_H

#include <math.h>

#define MAX_VARS 24
#define MAX_STATES 4
#define MAX_INDICATORS 4

typedef struct {
    double time;
    double r[MAX_VARS];  /* the Real variables, by value reference */
    int flags;           /* an integer discrete state, for the model's own use */
} ModelData;

/* sizes (model_n_vars <= MAX_VARS, ...) */
extern const int model_n_vars, model_n_states, model_n_indicators;
/* one character per value reference: 'p' a parameter (settable until the end of
 * initialization), 'i' an input (settable at any time), 'c' computed by the model
 * (a state, an output or a local variable: not settable) */
extern const char model_kinds[];
extern const unsigned model_state_vr[], model_derivative_vr[];

/* the start values of the parameters and inputs (the modelDescription.xml's) */
void model_start(ModelData *m);
/* the states and discrete states at the start time, from the parameters */
void model_initialize(ModelData *m);
/* the derivatives, outputs and locals from time, states, discrete states, inputs */
void model_compute(ModelData *m);
/* the event indicators (model_compute has just been called) */
void model_indicators(const ModelData *m, double z[]);
/* an event at m->time: update the discrete states and maybe re-initialize the states
 * (return 1 then, else 0); set *next_time to the time of the next time event, if any
 * (it is INFINITY on entry).  Must change nothing when no event condition holds. */
int model_event(ModelData *m, double *next_time);

/* t has reached a time event te (up to round-off) */
static inline int time_reached(double t, double te) {
    return t >= te - 1e-12 * (1.0 + fabs(te));
}

#endif
