/* A third-party FMI 2.0 co-simulation FMU written in plain C, for dsim's tests:
 * one mass m (kg) on a spring k (N/m) to ground, integrated with the trapezoidal
 * rule; the force input F_in (N) is held over a step and balanced at its end.
 * Its variables are named in its own way (F_in, s, v, a), so a glue:Port
 * annotation has to map them onto a port.  Compiled with -DNO_STATE it declares
 * and implements no state saving, the case a master must refuse to iterate; with
 * -DLIVE_OUTPUTS its outputs follow its inputs in initialization mode too (FMI 2.0
 * allows either).  A step longer than the parameter h_max (s; 0: no limit) is
 * discarded (fmi2Discard, state unchanged), as an FMU whose own solver cannot take
 * it would.  With -DCRASH_TIME=t its process ends abruptly (_exit) in the first
 * step that reaches t (t < 0: when it is instantiated), as a crashing FMU takes down
 * whatever process loads it.  With -DHANG_TIME=t the first step that reaches t never
 * returns, as an FMU stuck in its own solver; with -DHANG_INITIALIZATION
 * fmi2ExitInitializationMode never returns, after creating the file named by the
 * environment variable OSCILLATOR_HUNG (if set), so a test knows when it is stuck.
 * With -DHOG, once the file named by the environment variable OSCILLATOR_HOG exists,
 * its next step allocates and touches memory 64 MiB at a time, as an FMU with a runaway
 * allocation would, until the kernel's out-of-memory killer ends its process; it
 * gives up at 4 GiB (_exit(71)), so that a test whose memory limit did not hold fails
 * instead of filling the machine.
 * With -DINTERPOLATE it honours fmi2SetRealInputDerivatives (order 1, F_in only): the
 * force is F(t') = F + dF (t' - t_F) from the time t_F its value or slope was set (a
 * new fmi2SetReal holds it again: dF = 0), and the trapezoidal rule takes it at both
 * ends of a step, its acceleration at the start taken again from F there. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <fcntl.h>
#include "fmi2Functions.h"

enum { VR_M, VR_K, VR_F, VR_S, VR_V, VR_A, VR_S0, VR_HMAX, N_VARS };

typedef struct {
    double x[N_VARS];
    double time;
    int initializing;
#ifdef INTERPOLATE
    double dF, tF;  /* the force's slope (N/s) and when its value or slope was set (s) */
#endif
    fmi2CallbackFunctions cb;
    char name[64];
} Model;

static void update_acceleration(Model *m) {
    m->x[VR_A] = (m->x[VR_F] - m->x[VR_K] * m->x[VR_S]) / m->x[VR_M];
}

FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }
FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                           const fmi2String cats[]) { return fmi2OK; }

FMI2_Export fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean logging) {
#ifdef CRASH_TIME
    if (CRASH_TIME < 0) _exit(70);
#endif
    Model *m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cb = *functions;
    strncpy(m->name, name ? name : "", sizeof(m->name) - 1);
    m->x[VR_M] = 1.0; m->x[VR_K] = 1.0;
    return m;
}
FMI2_Export void fmi2FreeInstance(fmi2Component c) { free(c); }
FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined,
                                           fmi2Real tol, fmi2Real start,
                                           fmi2Boolean stopDefined, fmi2Real stop) {
    ((Model *)c)->time = start; return fmi2OK;
}
FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ((Model *)c)->initializing = 1;
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = c;
#ifdef HANG_INITIALIZATION
    const char *hung = getenv("OSCILLATOR_HUNG");
    if (hung != NULL) close(open(hung, O_WRONLY | O_CREAT | O_EXCL, 0600));
    for (;;) pause();
#endif
    m->x[VR_S] = m->x[VR_S0]; m->x[VR_V] = 0.0;
    update_acceleration(m);
    m->initializing = 0;
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
FMI2_Export fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                   fmi2Real value[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= N_VARS) return fmi2Error;
        value[i] = ((Model *)c)->x[vr[i]];
    }
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                   const fmi2Real value[]) {
    Model *m = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= N_VARS) return fmi2Error;
        m->x[vr[i]] = value[i];
#ifdef INTERPOLATE
        if (vr[i] == VR_F) { m->dF = 0.0; m->tF = m->time; }  /* held again */
#endif
#ifdef LIVE_OUTPUTS  /* in initialization mode the outputs follow the inputs at once */
        if (m->initializing && vr[i] == VR_S0) m->x[VR_S] = value[i];
#endif
    }
#ifdef LIVE_OUTPUTS
    if (m->initializing) update_acceleration(m);
#endif
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t n, fmi2Integer v[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Integer v[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t n, fmi2Boolean v[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[],
                                      size_t n, const fmi2Boolean v[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t n, fmi2String v[]) { return fmi2Error; }
FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[],
                                     size_t n, const fmi2String v[]) { return fmi2Error; }

#ifdef NO_STATE
#define STATE_RESULT fmi2Error
#else
#define STATE_RESULT fmi2OK
#endif
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
#ifdef NO_STATE
    return fmi2Error;
#else
    if (!*state) *state = malloc(sizeof(Model));
    if (!*state) return fmi2Error;
    memcpy(*state, c, sizeof(Model));
    return fmi2OK;
#endif
}
FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
#ifdef NO_STATE
    return fmi2Error;
#else
    memcpy(c, state, sizeof(Model));
    return fmi2OK;
#endif
}
FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    free(*state); *state = NULL; return STATE_RESULT;
}
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

#ifdef INTERPOLATE
/* the force's value at time t (N) */
static double force_at(const Model *m, double t) { return m->x[VR_F] + m->dF * (t - m->tF); }

FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
        const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
        const fmi2Real value[]) {
    Model *m = c;
    for (size_t i = 0; i < n; i++)
        if (vr[i] != VR_F || order[i] != 1) return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        m->x[VR_F] = force_at(m, m->time);  /* its value now, the slope from here on */
        m->tF = m->time;
        m->dF = value[i];
    }
    return fmi2OK;
}
#else
FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c,
        const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
        const fmi2Real value[]) { return fmi2Error; }
#endif
FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c,
        const fmi2ValueReference vr[], size_t n, const fmi2Integer order[],
        fmi2Real value[]) { return fmi2Error; }

/* trapezoidal rule: s1 = s + h v + h^2/4 (a + a1), v1 = v + h/2 (a + a1),
 * m a1 + k s1 = F  =>  a1 = (F - k (s + h v + h^2/4 a)) / (m + k h^2/4) */
FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h,
                                  fmi2Boolean noSetPrior) {
    Model *m = c;
    double *x = m->x;
#ifdef CRASH_TIME
    if (t + h >= CRASH_TIME) _exit(70);
#endif
#ifdef HANG_TIME
    while (t + h >= HANG_TIME) pause();
#endif
#ifdef HOG
    {
        const char *trigger = getenv("OSCILLATOR_HOG");
        if (trigger && access(trigger, F_OK) == 0) {
            size_t chunk = (size_t)64 << 20;
            for (int k = 0; k < 64; k++) {
                char *block = malloc(chunk);
                if (block) memset(block, 1, chunk);  /* touched: charged to the process */
            }
            _exit(71);
        }
    }
#endif
    if (x[VR_HMAX] > 0.0 && h > x[VR_HMAX] * (1.0 + 1e-12)) {
        m->cb.logger(m->cb.componentEnvironment, m->name, fmi2Discard, "logStatusDiscard",
                     "step of %g s is longer than h_max", h);
        return fmi2Discard;
    }
#ifdef INTERPOLATE
    double f1 = force_at(m, t + h);
    x[VR_A] = (force_at(m, t) - x[VR_K] * x[VR_S]) / x[VR_M];
#else
    double f1 = x[VR_F];
#endif
    double s_pred = x[VR_S] + h * x[VR_V] + 0.25 * h * h * x[VR_A];
    double a1 = (f1 - x[VR_K] * s_pred) / (x[VR_M] + 0.25 * h * h * x[VR_K]);
    x[VR_V] += 0.5 * h * (x[VR_A] + a1);
    x[VR_S] = s_pred + 0.25 * h * h * a1;
    x[VR_A] = a1;
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
