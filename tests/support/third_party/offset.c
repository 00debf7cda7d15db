/* A plain-C FMI 2.0 co-simulation FMU for dsim's scenario tests: in each fmi2DoStep it
 * adds a constant to each input, the way libcosim's test slave for scenarios does
 *
 *     realOut = realIn + offset      (offset: a tunable Real parameter, 1.234)
 *     intOut  = intIn + intStep      (intStep: a fixed Integer parameter, 2)
 *     flagOut = flag                 (Boolean)
 *     labelOut = label               (String)
 *
 * and reports the inputs it stepped with (realInEcho, intInEcho), since a results CSV
 * records outputs only.  Value references: Real, Integer, Boolean and String variables
 * are numbered separately, as the enums below (tests/support/third_party/build.py:
 * OFFSET_VARIABLES declares them).
 *
 * Its inputs start at their declared starts (realIn 1.0, intIn 1) and its outputs are
 * computed from them when initialization ends.  Compiled with -DMOCK_INPUTS_ZERO it holds
 * 0 in both inputs until a master writes them, while its modelDescription still declares
 * 1.0 and 1, and its outputs start at 1.0 and 1: what libcosim's mock slave does (a
 * declared start that disagrees with the behaviour, kept only to reproduce libcosim's
 * expected numbers exactly). */
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include "fmi2Functions.h"

enum { R_OUT, R_IN, R_IN_ECHO, R_OFFSET, R_VERSION, N_REALS };
enum { I_OUT, I_IN, I_IN_ECHO, I_STEP, N_INTEGERS };
enum { B_FLAG, B_FLAG_OUT, N_BOOLEANS };
enum { S_LABEL, S_LABEL_OUT, N_STRINGS };
#define TEXT 128

typedef struct {
    double r[N_REALS];
    int i[N_INTEGERS];
    int b[N_BOOLEANS];
    char s[N_STRINGS][TEXT];
} Model;

FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }
FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                           const fmi2String cats[]) { return fmi2OK; }

FMI2_Export fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                          fmi2String resources,
                                          const fmi2CallbackFunctions *functions,
                                          fmi2Boolean visible, fmi2Boolean logging) {
    Model *m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->r[R_OFFSET] = 1.234;
    m->r[R_VERSION] = 1.0;
    m->i[I_STEP] = 2;
#ifdef MOCK_INPUTS_ZERO
    m->r[R_IN] = 0.0;  /* libcosim's mock: 0 held, 1.0 declared */
    m->i[I_IN] = 0;
#else
    m->r[R_IN] = 1.0;
    m->i[I_IN] = 1;
#endif
    return m;
}
FMI2_Export void fmi2FreeInstance(fmi2Component c) { free(c); }
FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined,
                                           fmi2Real tol, fmi2Real start,
                                           fmi2Boolean stopDefined, fmi2Real stop) {
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = c;
#ifdef MOCK_INPUTS_ZERO
    m->r[R_OUT] = 1.0;  /* the mock's first outputs */
    m->i[I_OUT] = 1;
#else
    m->r[R_OUT] = m->r[R_IN] + m->r[R_OFFSET];
    m->i[I_OUT] = m->i[I_IN] + m->i[I_STEP];
#endif
    m->r[R_IN_ECHO] = m->r[R_IN];
    m->i[I_IN_ECHO] = m->i[I_IN];
    m->b[B_FLAG_OUT] = m->b[B_FLAG];
    snprintf(m->s[S_LABEL_OUT], TEXT, "%s", m->s[S_LABEL]);
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
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
        if (vr[k] != S_LABEL) return fmi2Error;
        snprintf(m->s[vr[k]], TEXT, "%s", v[k] ? v[k] : "");
    }
    return fmi2OK;
}

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
FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    *n = sizeof(Model); return fmi2OK;
}
FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[],
                                             size_t n) {
    if (n < sizeof(Model)) return fmi2Error;
    memcpy(b, s, sizeof(Model));
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                               fmi2FMUstate *s) {
    if (n != sizeof(Model)) return fmi2Error;
    *s = malloc(sizeof(Model));
    if (!*s) return fmi2Error;
    memcpy(*s, b, sizeof(Model));
    return fmi2OK;
}
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
    m->r[R_OUT] = m->r[R_IN] + m->r[R_OFFSET];
    m->r[R_IN_ECHO] = m->r[R_IN];
    m->i[I_OUT] = m->i[I_IN] + m->i[I_STEP];
    m->i[I_IN_ECHO] = m->i[I_IN];
    m->b[B_FLAG_OUT] = m->b[B_FLAG];
    snprintf(m->s[S_LABEL_OUT], TEXT, "%s", m->s[S_LABEL]);
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
