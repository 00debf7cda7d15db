/* The FMI 2.0 skeleton of the models of this folder: Model Exchange and Co-Simulation
 * in one binary (fmi2Instantiate's fmuType chooses).  Only Real variables; the
 * Integer, Boolean and String getters and setters accept zero-length calls only.
 * Co-simulation steps with core.c's RK4 integrator, events handled inside the step,
 * and interpolates its inputs linearly after fmi2SetRealInputDerivatives (order 1;
 * a new fmi2SetReal of the input holds it again).  FMU states are copies of the
 * instance's Core; with -DNO_STATE the FMU-state functions return fmi2Error.
 * Compile with -DMODEL_GUID='"{...}"' (the modelDescription.xml's guid). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"
#include "core.h"

#ifndef MODEL_GUID
#error "compile with -DMODEL_GUID=<the guid of the modelDescription.xml>"
#endif

typedef struct {
    Core core;  /* all the model's state: what an FMU state copies */
    fmi2Type type;
    char name[128];
    fmi2CallbackFunctions cb;
} Instance;

static void logf2(Instance *m, fmi2Status status, const char *message) {
    if (m->cb.logger)
        m->cb.logger(m->cb.componentEnvironment, m->name, status,
                     status == fmi2OK ? "logAll" : "logStatusError", message);
}

/* fmi2Error, logged, for a failed core call */
static fmi2Status failed(Instance *m, const char *function, int code, unsigned vr) {
    char message[256];
    const char *why = code == CORE_UNKNOWN_VR ? "unknown value reference"
                      : code == CORE_NOT_SETTABLE ? "variable not settable now"
                      : "bad argument";
    snprintf(message, sizeof(message), "%s: %s (%u)", function, why, vr);
    logf2(m, fmi2Error, message);
    return fmi2Error;
}

#define INSTANCE(c) Instance *m = (Instance *)(c); if (!m) return fmi2Error
#define CHECK(function, call) do { unsigned bad_ = 0; int code_ = (call); \
        if (code_ != CORE_OK) return failed(m, function, code_, bad_); } while (0)

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String categories[]) {
    INSTANCE(c);
    (void)on; (void)n; (void)categories;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean logging) {
    (void)resources; (void)visible; (void)logging;
    if (type != fmi2ModelExchange && type != fmi2CoSimulation) return NULL;
    Instance *m = calloc(1, sizeof(Instance));
    if (!m) return NULL;
    if (functions) m->cb = *functions;
    snprintf(m->name, sizeof(m->name), "%s", name ? name : "");
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        logf2(m, fmi2Error, "fmi2Instantiate: the guid is not this FMU's");
        free(m);
        return NULL;
    }
    m->type = type;
    core_reset(&m->core, type == fmi2CoSimulation);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stopDefined, fmi2Real stop) {
    INSTANCE(c);
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    m->core.d.time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    INSTANCE(c);
    core_enter_initialization(&m->core, m->core.d.time);
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    INSTANCE(c);
    core_exit_initialization(&m->core);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    INSTANCE(c);
    m->core.phase = PHASE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    INSTANCE(c);
    core_reset(&m->core, m->type == fmi2CoSimulation);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       fmi2Real value[]) {
    INSTANCE(c);
    CHECK("fmi2GetReal", core_get_reals(&m->core, vr, n, value, &bad_));
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real value[]) {
    INSTANCE(c);
    CHECK("fmi2SetReal", core_set_reals(&m->core, vr, n, value, &bad_));
    return fmi2OK;
}

/* no Integer, Boolean or String variables: only empty calls succeed */
#define NONE_OF_TYPE(function) \
    INSTANCE(c); (void)value; \
    if (n == 0) return fmi2OK; \
    return failed(m, function, CORE_UNKNOWN_VR, vr ? vr[0] : 0)

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer value[]) { NONE_OF_TYPE("fmi2GetInteger"); }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer value[]) { NONE_OF_TYPE("fmi2SetInteger"); }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Boolean value[]) { NONE_OF_TYPE("fmi2GetBoolean"); }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean value[]) { NONE_OF_TYPE("fmi2SetBoolean"); }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         fmi2String value[]) { NONE_OF_TYPE("fmi2GetString"); }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String value[]) { NONE_OF_TYPE("fmi2SetString"); }

/* ---- FMU states: copies of the Core ---- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    logf2(m, fmi2Error, "fmi2GetFMUstate: not supported");
    return fmi2Error;
#else
    if (!state) return fmi2Error;
    if (!*state) *state = malloc(sizeof(Core));
    if (!*state) return fmi2Error;
    memcpy(*state, &m->core, sizeof(Core));
    return fmi2OK;
#endif
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    logf2(m, fmi2Error, "fmi2SetFMUstate: not supported");
    return fmi2Error;
#else
    if (!state) return fmi2Error;
    memcpy(&m->core, state, sizeof(Core));
    return fmi2OK;
#endif
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    return fmi2Error;
#else
    if (!state) return fmi2Error;
    free(*state);
    *state = NULL;
    return fmi2OK;
#endif
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state; (void)size;
    return fmi2Error;
#else
    if (!state || !size) return fmi2Error;
    *size = sizeof(Core);
    return fmi2OK;
#endif
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[],
                                 size_t size) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state; (void)bytes; (void)size;
    return fmi2Error;
#else
    if (!state || !bytes || size != sizeof(Core)) return fmi2Error;
    memcpy(bytes, state, sizeof(Core));
    return fmi2OK;
#endif
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                   fmi2FMUstate *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)bytes; (void)size; (void)state;
    return fmi2Error;
#else
    if (!bytes || !state || size != sizeof(Core)) return fmi2Error;
    if (!*state) *state = malloc(sizeof(Core));
    if (!*state) return fmi2Error;
    memcpy(*state, bytes, sizeof(Core));
    return fmi2OK;
#endif
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference z[],
                                        size_t nz, const fmi2ValueReference v[], size_t nv,
                                        const fmi2Real dv[], fmi2Real dz[]) {
    INSTANCE(c);
    (void)z; (void)nz; (void)v; (void)nv; (void)dv; (void)dz;
    logf2(m, fmi2Error, "fmi2GetDirectionalDerivative: not provided");
    return fmi2Error;
}

/* ---- Model Exchange ---- */

#define ME_INSTANCE(c) INSTANCE(c); \
    if (m->type != fmi2ModelExchange) return failed(m, __func__, CORE_BAD_ARGUMENT, 0)

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    ME_INSTANCE(c);
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    ME_INSTANCE(c);
    if (!info) return fmi2Error;
    int reinit = core_event_update(&m->core);
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = reinit ? fmi2True : fmi2False;
    info->nextEventTimeDefined = isfinite(m->core.next_event) ? fmi2True : fmi2False;
    info->nextEventTime = info->nextEventTimeDefined ? m->core.next_event : 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    ME_INSTANCE(c);
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetPrior,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminate) {
    ME_INSTANCE(c);
    (void)noSetPrior;
    if (!enterEventMode || !terminate) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminate = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    ME_INSTANCE(c);
    core_set_time(&m->core, time);
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    ME_INSTANCE(c);
    if (nx != (size_t)model_n_states || (nx > 0 && !x))
        return failed(m, "fmi2SetContinuousStates", CORE_BAD_ARGUMENT, (unsigned)nx);
    core_set_states(&m->core, x);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    ME_INSTANCE(c);
    if (nx != (size_t)model_n_states || (nx > 0 && !x))
        return failed(m, "fmi2GetContinuousStates", CORE_BAD_ARGUMENT, (unsigned)nx);
    core_get_states(&m->core, x);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    ME_INSTANCE(c);
    if (nx != (size_t)model_n_states || (nx > 0 && !dx))
        return failed(m, "fmi2GetDerivatives", CORE_BAD_ARGUMENT, (unsigned)nx);
    core_get_derivatives(&m->core, dx);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    ME_INSTANCE(c);
    if (nz != (size_t)model_n_indicators || (nz > 0 && !z))
        return failed(m, "fmi2GetEventIndicators", CORE_BAD_ARGUMENT, (unsigned)nz);
    core_get_indicators(&m->core, z);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real nominal[],
                                             size_t nx) {
    ME_INSTANCE(c);
    if (nx != (size_t)model_n_states || (nx > 0 && !nominal))
        return failed(m, "fmi2GetNominalsOfContinuousStates", CORE_BAD_ARGUMENT,
                      (unsigned)nx);
    for (size_t i = 0; i < nx; i++) nominal[i] = 1.0;
    return fmi2OK;
}

/* ---- Co-Simulation ---- */

#define CS_INSTANCE(c) INSTANCE(c); \
    if (m->type != fmi2CoSimulation) return failed(m, __func__, CORE_BAD_ARGUMENT, 0)

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t n, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    CS_INSTANCE(c);
    if (n > 0 && (!vr || !order || !value)) return fmi2Error;
    for (size_t i = 0; i < n; i++)
        CHECK("fmi2SetRealInputDerivatives",
              core_set_input_derivative(&m->core, vr[i], order[i], value[i], &bad_));
    return fmi2OK;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t n, const fmi2Integer order[],
                                        fmi2Real value[]) {
    CS_INSTANCE(c);
    (void)order; (void)value;
    if (n == 0) return fmi2OK;
    return failed(m, "fmi2GetRealOutputDerivatives (maxOutputDerivativeOrder=0)",
                  CORE_BAD_ARGUMENT, vr ? vr[0] : 0);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    CS_INSTANCE(c);
    (void)noSetPrior;
    if (m->core.phase != PHASE_RUNNING)
        return failed(m, "fmi2DoStep: not initialized", CORE_BAD_ARGUMENT, 0);
    CHECK("fmi2DoStep", core_do_step(&m->core, t, h));
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    CS_INSTANCE(c);
    return fmi2Error;  /* fmi2DoStep never returns fmi2Pending */
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    CS_INSTANCE(c);
    if (s != fmi2DoStepStatus || !value) return fmi2Discard;
    *value = fmi2OK;
    return fmi2OK;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CS_INSTANCE(c);
    if (s != fmi2LastSuccessfulTime || !value) return fmi2Discard;
    *value = m->core.d.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Integer *value) {
    CS_INSTANCE(c);
    (void)s; (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s,
                                fmi2Boolean *value) {
    CS_INSTANCE(c);
    if (s != fmi2Terminated || !value) return fmi2Discard;
    *value = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    CS_INSTANCE(c);
    (void)s; (void)value;
    return fmi2Discard;
}
