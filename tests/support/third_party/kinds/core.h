/* What the FMI 1.0, 2.0 and 3.0 skeletons share: one instance of a model (model.h)
 * with its phase, its inputs (with slopes, for co-simulation's interpolated inputs),
 * its next time event, and the co-simulation step: a fixed-substep RK4 integrator
 * (substeps of at most CORE_MAX_SUBSTEP) that locates state events by bisection and
 * hits time events exactly.  A Core is plain data: an FMU state is a copy of it. */
#ifndef KINDS_CORE_H
#define KINDS_CORE_H

#include <stddef.h>
#include "model.h"

#ifndef CORE_MAX_SUBSTEP
#define CORE_MAX_SUBSTEP 1e-4
#endif

enum { PHASE_INSTANTIATED, PHASE_INITIALIZATION, PHASE_RUNNING, PHASE_TERMINATED };
enum { CORE_OK = 0, CORE_UNKNOWN_VR = -1, CORE_NOT_SETTABLE = -2, CORE_BAD_ARGUMENT = -3 };

typedef struct {
    ModelData d;
    /* input vr at time t: u[vr] + du[vr] * (t - t_u[vr]) */
    double u[MAX_VARS], du[MAX_VARS], t_u[MAX_VARS];
    double next_event;  /* time of the next time event, INFINITY when none */
    int phase;
    int co_simulation;
} Core;

void core_reset(Core *c, int co_simulation);
void core_enter_initialization(Core *c, double start_time);
void core_exit_initialization(Core *c);
/* on error *bad is the offending value reference */
int core_get_reals(Core *c, const unsigned vr[], size_t n, double value[], unsigned *bad);
int core_set_reals(Core *c, const unsigned vr[], size_t n, const double value[],
                   unsigned *bad);
/* the slope of an input from now on (order must be 1) */
int core_set_input_derivative(Core *c, unsigned vr, int order, double value,
                              unsigned *bad);
/* model exchange */
void core_set_time(Core *c, double t);
void core_set_states(Core *c, const double x[]);
void core_get_states(const Core *c, double x[]);
void core_get_derivatives(Core *c, double dx[]);
void core_get_indicators(Core *c, double z[]);
/* an event at the current time; returns 1 when the states were re-initialized */
int core_event_update(Core *c);
/* co-simulation: from t to t + h (CORE_BAD_ARGUMENT when h < 0) */
int core_do_step(Core *c, double t, double h);

#endif
