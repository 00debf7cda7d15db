/* A third-party FMI 2.0 co-simulation FMU written in plain C, for dsim's tests and
 * benchmarks: a causal signal block, a first-order lag
 *
 *     tau dy/dt = gain (u + extra) - y        (u Real, extra Integer inputs)
 *
 * stepped exactly over each communication step with the inputs held.  Outputs: y,
 * count (Integer: steps taken), positive (Boolean: y > 0).  Boolean input enable:
 * when false the block holds y.  String parameter label, String input note, String
 * output status = "label:note:count" (written after every step).  It can be told to fail at t >= fail_time
 * (Integer parameter failure): 1 y becomes NaN, 2 fmi2DoStep returns fmi2Error,
 * 3 fmi2DoStep returns fmi2Discard, 4 the process aborts (a crashing FMU), 5 fmi2DoStep
 * returns fmi2Fatal; after 2 or 3, fmi2Terminate fails too (a cleanup that must not
 * hide the first error).  failure 6 and 7 make fmi2ExitInitializationMode return
 * fmi2Error and fmi2Fatal.  failure 8 makes it check its stop time as some tools' FMUs
 * do: a step that would end past the stopTime of fmi2SetupExperiment, by any amount
 * (round-off too), returns fmi2Error.  Compiled with -DINSTANTIATE_FAILS=3 (or 4) fmi2Instantiate
 * logs an error (a fatal error) and returns NULL; with -DNO_STATE it implements no
 * state saving.  Compiled with -DCHATTY it logs CHATTY messages of category logEvents
 * per step while that category is on (every category is at instantiation with logging
 * on; fmi2SetDebugLogging chooses), counting them in the Integer output logged, as
 * some tools' FMUs log every event. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

/* value references: Real, Integer and Boolean variables are numbered separately */
enum { R_GAIN, R_TAU, R_Y0, R_FAIL_TIME, R_U, R_Y, N_REALS };
enum { I_FAILURE, I_EXTRA, I_COUNT, I_LOGGED, N_INTEGERS };
enum { B_ENABLE, B_POSITIVE, N_BOOLEANS };
enum { S_LABEL, S_NOTE, S_STATUS, N_STRINGS };
#define TEXT 256

typedef struct {
    double r[N_REALS];
    int i[N_INTEGERS];
    int b[N_BOOLEANS];
    char s[N_STRINGS][TEXT];
    double time;
    double stop;      /* fmi2SetupExperiment's stopTime, when defined */
    int stop_defined;
    int failed;  /* a simulated failure happened: fmi2Terminate fails too */
    int events;  /* the logEvents category is on */
    char name[128];
    fmi2CallbackFunctions cb;
} Model;

static void log_message(Model *m, fmi2Status status, const char *text) {
    if (m->cb.logger) m->cb.logger(m->cb.componentEnvironment, m->name, status,
                                   status == fmi2OK ? "info" : "error", "%s", text);
}

FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }
FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                           const fmi2String cats[]) {
    Model *m = c;
    m->events = on && n == 0;  /* no category named: all of them */
    for (size_t k = 0; on && k < n; k++)
        if (cats[k] && strcmp(cats[k], "logEvents") == 0) m->events = 1;
    return fmi2OK;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean logging) {
#ifdef INSTANTIATE_FAILS
    if (functions->logger)
        functions->logger(functions->componentEnvironment, name, INSTANTIATE_FAILS, "error",
                          "block: simulated failure to instantiate");
    return NULL;
#endif
    Model *m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cb = *functions;
    m->events = logging;
    snprintf(m->name, sizeof m->name, "%s", name ? name : "block");
    m->r[R_GAIN] = 0.9; m->r[R_TAU] = 0.1; m->r[R_Y0] = 1.0; m->r[R_FAIL_TIME] = 1e300;
    m->b[B_ENABLE] = fmi2True;
    snprintf(m->s[S_LABEL], TEXT, "block");
    return m;
}
FMI2_Export void fmi2FreeInstance(fmi2Component c) {
    log_message(c, fmi2OK, "block: instance freed");  /* tests see that the master frees it */
    free(c);
}
FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined,
                                           fmi2Real tol, fmi2Real start,
                                           fmi2Boolean stopDefined, fmi2Real stop) {
    Model *m = c;
    m->time = start;
    m->stop = stop;
    m->stop_defined = stopDefined;
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = c;
    if (m->i[I_FAILURE] == 6 || m->i[I_FAILURE] == 7) {
        fmi2Status status = m->i[I_FAILURE] == 6 ? fmi2Error : fmi2Fatal;
        log_message(m, status, "block: simulated failure to initialise");
        return status;
    }
    m->r[R_Y] = m->r[R_Y0];
    m->b[B_POSITIVE] = m->r[R_Y] > 0.0;
    snprintf(m->s[S_STATUS], TEXT, "%.60s:%.120s:%d", m->s[S_LABEL], m->s[S_NOTE], 0);
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    Model *m = c;
    if (m->failed) {
        log_message(m, fmi2Error, "block: cannot terminate cleanly after the failure");
        return fmi2Error;
    }
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }

#define ACCESS(NAME, TYPE, FIELD, COUNT, CONST)                                         \
    FMI2_Export fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[],        \
                                size_t n, CONST TYPE value[]) {                         \
        Model *m = c;                                                                   \
        for (size_t k = 0; k < n; k++) {                                                \
            if (vr[k] >= COUNT) return fmi2Error;                                       \
            GETSET(m->FIELD[vr[k]], value[k]);                                          \
        }                                                                               \
        return fmi2OK;                                                                  \
    }
#define GETSET(var, val) (val) = (var)
ACCESS(fmi2GetReal, fmi2Real, r, N_REALS, )
ACCESS(fmi2GetInteger, fmi2Integer, i, N_INTEGERS, )
ACCESS(fmi2GetBoolean, fmi2Boolean, b, N_BOOLEANS, )
#undef GETSET
#define GETSET(var, val) (var) = (val)
ACCESS(fmi2SetReal, fmi2Real, r, N_REALS, const)
ACCESS(fmi2SetInteger, fmi2Integer, i, N_INTEGERS, const)
ACCESS(fmi2SetBoolean, fmi2Boolean, b, N_BOOLEANS, const)
#undef GETSET

FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t n, fmi2String v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_STRINGS) return fmi2Error;
        v[k] = m->s[vr[k]];
    }
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t n, const fmi2String v[]) {
    Model *m = c;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_STRINGS || vr[k] == S_STATUS) return fmi2Error;
        snprintf(m->s[vr[k]], TEXT, "%s", v[k] ? v[k] : "");
    }
    return fmi2OK;
}

#ifdef NO_STATE
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { return fmi2Error; }
FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
#else
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    if (!*state) *state = malloc(sizeof(Model));
    if (!*state) return fmi2Error;
    memcpy(*state, c, sizeof(Model));
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    memcpy(c, state, sizeof(Model));
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    free(*state); *state = NULL; return fmi2OK;
}
#endif
FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    return fmi2Error;
}
FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[],
                                             size_t n) { return fmi2Error; }
FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                               fmi2FMUstate *s) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
        const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[], size_t nz,
        const fmi2Real du[], fmi2Real dz[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
        const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
        const fmi2Real value[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
        const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
        fmi2Real value[]) { return fmi2Error; }

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h,
                                  fmi2Boolean noSetPrior) {
    Model *m = c;
    double *r = m->r;
    if (m->i[I_FAILURE] == 8 && m->stop_defined && t + h > m->stop) {
        char text[160];
        snprintf(text, sizeof text, "block: Exceeded model finish time: %.17g > %.17g",
                 t + h, m->stop);
        log_message(m, fmi2Error, text);
        return fmi2Error;
    }
    if (t + h >= r[R_FAIL_TIME]) {
        char text[160];
        m->failed = m->i[I_FAILURE] > 1;
        switch (m->i[I_FAILURE]) {
        case 1: r[R_Y] = NAN; m->time = t + h; return fmi2OK;
        case 2:
            snprintf(text, sizeof text, "block: simulated solver failure at t = %g", t + h);
            log_message(m, fmi2Error, text);
            return fmi2Error;
        case 3:
            snprintf(text, sizeof text, "block: step to t = %g rejected", t + h);
            log_message(m, fmi2Discard, text);
            return fmi2Discard;
        case 4: abort();
        case 5:
            snprintf(text, sizeof text, "block: simulated fatal failure at t = %g", t + h);
            log_message(m, fmi2Fatal, text);
            return fmi2Fatal;
        default: break;
        }
    }
    if (m->b[B_ENABLE]) {
        double target = r[R_GAIN] * (r[R_U] + m->i[I_EXTRA]);
        r[R_Y] = target + (r[R_Y] - target) * exp(-h / r[R_TAU]);
    }
    m->i[I_COUNT] += 1;
#ifdef CHATTY
    for (int k = 0; m->events && m->cb.logger && k < CHATTY; k++) {
        m->cb.logger(m->cb.componentEnvironment, m->name, fmi2OK, "logEvents",
                     "block: event %d of the step to t = %g", k, t + h);
        m->i[I_LOGGED] += 1;
    }
#endif
    m->b[B_POSITIVE] = r[R_Y] > 0.0;
    snprintf(m->s[S_STATUS], TEXT, "%.60s:%.120s:%d", m->s[S_LABEL], m->s[S_NOTE],
             m->i[I_COUNT]);
    m->time = t + h;
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s,
                                     fmi2Status *v) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s,
                                         fmi2Real *v) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Integer *v) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                            fmi2Boolean *v) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s,
                                           fmi2String *v) { return fmi2Error; }
