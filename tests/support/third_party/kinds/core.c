/* The API-independent part of the FMUs of this folder (see core.h). */
#include <string.h>
#include "core.h"

void core_reset(Core *c, int co_simulation) {
    memset(c, 0, sizeof(*c));
    c->co_simulation = co_simulation;
    c->next_event = INFINITY;
    c->phase = PHASE_INSTANTIATED;
    model_start(&c->d);
    for (int i = 0; i < model_n_vars; i++) c->u[i] = c->d.r[i];
}

/* the inputs at time t (held or, with slopes, linear in t) */
static void apply_inputs(Core *c, double t) {
    c->d.time = t;
    for (int i = 0; i < model_n_vars; i++)
        if (model_kinds[i] == 'i') c->d.r[i] = c->u[i] + c->du[i] * (t - c->t_u[i]);
}

/* recompute every computed variable (before initialization ends: from the parameters) */
static void refresh(Core *c) {
    apply_inputs(c, c->d.time);
    if (c->phase < PHASE_RUNNING) model_initialize(&c->d);
    model_compute(&c->d);
}

void core_enter_initialization(Core *c, double start_time) {
    c->d.time = start_time;
    for (int i = 0; i < model_n_vars; i++) c->t_u[i] = start_time;
    c->phase = PHASE_INITIALIZATION;
}

void core_exit_initialization(Core *c) {
    refresh(c);
    c->phase = PHASE_RUNNING;
    core_event_update(c);  /* the initial event (schedules the first time event) */
}

int core_get_reals(Core *c, const unsigned vr[], size_t n, double value[], unsigned *bad) {
    if (n > 0 && (!vr || !value)) return CORE_BAD_ARGUMENT;
    refresh(c);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= (unsigned)model_n_vars) { *bad = vr[i]; return CORE_UNKNOWN_VR; }
        value[i] = c->d.r[vr[i]];
    }
    return CORE_OK;
}

int core_set_reals(Core *c, const unsigned vr[], size_t n, const double value[],
                   unsigned *bad) {
    if (n > 0 && (!vr || !value)) return CORE_BAD_ARGUMENT;
    for (size_t i = 0; i < n; i++) {  /* check all before setting any */
        if (vr[i] >= (unsigned)model_n_vars) { *bad = vr[i]; return CORE_UNKNOWN_VR; }
        char kind = model_kinds[vr[i]];
        if (kind == 'c' || (kind == 'p' && c->phase >= PHASE_RUNNING)) {
            *bad = vr[i];
            return CORE_NOT_SETTABLE;
        }
    }
    for (size_t i = 0; i < n; i++) {
        unsigned v = vr[i];
        c->d.r[v] = value[i];
        if (model_kinds[v] == 'i') {  /* a new value: held until a slope is set */
            c->u[v] = value[i];
            c->du[v] = 0.0;
            c->t_u[v] = c->d.time;
        }
    }
    return CORE_OK;
}

int core_set_input_derivative(Core *c, unsigned vr, int order, double value,
                              unsigned *bad) {
    *bad = vr;
    if (vr >= (unsigned)model_n_vars) return CORE_UNKNOWN_VR;
    if (model_kinds[vr] != 'i') return CORE_NOT_SETTABLE;
    if (order != 1) return CORE_BAD_ARGUMENT;
    c->u[vr] += c->du[vr] * (c->d.time - c->t_u[vr]);  /* its value now */
    c->t_u[vr] = c->d.time;
    c->du[vr] = value;
    return CORE_OK;
}

void core_set_time(Core *c, double t) { apply_inputs(c, t); }

void core_set_states(Core *c, const double x[]) {
    for (int i = 0; i < model_n_states; i++) c->d.r[model_state_vr[i]] = x[i];
}

void core_get_states(const Core *c, double x[]) {
    for (int i = 0; i < model_n_states; i++) x[i] = c->d.r[model_state_vr[i]];
}

void core_get_derivatives(Core *c, double dx[]) {
    refresh(c);
    for (int i = 0; i < model_n_states; i++) dx[i] = c->d.r[model_derivative_vr[i]];
}

void core_get_indicators(Core *c, double z[]) {
    refresh(c);
    model_indicators(&c->d, z);
}

int core_event_update(Core *c) {
    double next = INFINITY;
    refresh(c);
    int reinit = model_event(&c->d, &next);
    c->next_event = next;
    model_compute(&c->d);
    return reinit;
}

/* ---- co-simulation ---- */

/* derivatives (dx) and event indicators (z) at (t, x); either may be NULL */
static void eval(Core *c, double t, const double x[], double dx[], double z[]) {
    apply_inputs(c, t);
    core_set_states(c, x);
    model_compute(&c->d);
    if (dx) for (int i = 0; i < model_n_states; i++) dx[i] = c->d.r[model_derivative_vr[i]];
    if (z) model_indicators(&c->d, z);
}

/* one classical Runge-Kutta step of h from (t, x0) to x1 */
static void rk4(Core *c, double t, double h, const double x0[], double x1[]) {
    double k[4][MAX_STATES] = {{0.0}}, xt[MAX_STATES] = {0.0};
    int n = model_n_states;
    eval(c, t, x0, k[0], NULL);
    for (int i = 0; i < n; i++) xt[i] = x0[i] + 0.5 * h * k[0][i];
    eval(c, t + 0.5 * h, xt, k[1], NULL);
    for (int i = 0; i < n; i++) xt[i] = x0[i] + 0.5 * h * k[1][i];
    eval(c, t + 0.5 * h, xt, k[2], NULL);
    for (int i = 0; i < n; i++) xt[i] = x0[i] + h * k[2][i];
    eval(c, t + h, xt, k[3], NULL);
    for (int i = 0; i < n; i++)
        x1[i] = x0[i] + h / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
}

/* an event indicator left a side of zero between z0 and z1 */
static int crossed(const double z0[], const double z1[]) {
    for (int i = 0; i < model_n_indicators; i++)
        if ((z0[i] > 0.0 && z1[i] <= 0.0) || (z0[i] < 0.0 && z1[i] >= 0.0)) return 1;
    return 0;
}

int core_do_step(Core *c, double t, double h) {
    double x[MAX_STATES], x1[MAX_STATES], z[MAX_INDICATORS], z1[MAX_INDICATORS];
    double t_end = t + h;
    if (!(h >= 0.0) || !isfinite(t_end)) return CORE_BAD_ARGUMENT;
    c->d.time = t;
    core_get_states(c, x);
    for (;;) {
        if (time_reached(c->d.time, c->next_event)) {  /* a time event: now */
            core_set_states(c, x);
            core_event_update(c);
            core_get_states(c, x);
            if (time_reached(c->d.time, c->next_event)) c->next_event = INFINITY;
        }
        if (c->d.time >= t_end) break;
        /* equal substeps of at most CORE_MAX_SUBSTEP up to the end or the time event */
        double t0 = c->d.time, target = fmin(t_end, c->next_event);
        double substeps = ceil((target - t0) / CORE_MAX_SUBSTEP - 1e-9);
        double t1 = substeps <= 1.0 ? target : t0 + (target - t0) / substeps;
        eval(c, t0, x, NULL, z);
        rk4(c, t0, t1 - t0, x, x1);
        eval(c, t1, x1, NULL, z1);
        int state_event = crossed(z, z1);
        if (state_event) {  /* bisection: the event lies in (t0 + lo, t0 + hi] */
            double lo = 0.0, hi = t1 - t0;
            for (int i = 0; i < 80 && hi - lo > 1e-15 * (1.0 + fabs(t0)); i++) {
                double mid = 0.5 * (lo + hi);
                rk4(c, t0, mid, x, x1);
                eval(c, t0 + mid, x1, NULL, z1);
                if (crossed(z, z1)) hi = mid; else lo = mid;
            }
            t1 = t0 + hi;
            rk4(c, t0, hi, x, x1);
        }
        memcpy(x, x1, sizeof(x));
        c->d.time = t1;
        if (state_event) {
            core_set_states(c, x);
            core_event_update(c);
            core_get_states(c, x);
        }
    }
    c->d.time = t_end;
    core_set_states(c, x);
    refresh(c);
    return CORE_OK;
}
