/* The FMI 3.0 skeleton of the models of this folder: Model Exchange and Co-Simulation
 * in one binary.  Only Float64 variables (plus the independent variable time, value
 * reference TIME_VR); the other getters and setters accept zero-length calls only.
 * Co-simulation has no event mode and no intermediate update: fmi3DoStep integrates
 * with core.c's RK4 integrator and handles events inside the step.  FMU states are
 * copies of the instance's Core; with -DNO_STATE the FMU-state functions return
 * fmi3Error.  Compile with -DMODEL_GUID='"{...}"' (the instantiationToken). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"
#include "core.h"

#ifndef MODEL_GUID
#error "compile with -DMODEL_GUID=<the instantiationToken of the modelDescription.xml>"
#endif
#ifndef TIME_VR
#define TIME_VR 1000
#endif

enum { ME, CS };

typedef struct {
    Core core;  /* all the model's state: what an FMU state copies */
    int type;
    char name[128];
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

static fmi3Status failed(Instance *m, const char *function, int code, unsigned vr) {
    char message[256];
    const char *why = code == CORE_UNKNOWN_VR ? "unknown value reference"
                      : code == CORE_NOT_SETTABLE ? "variable not settable now"
                      : "bad argument";
    snprintf(message, sizeof(message), "%s: %s (%u)", function, why, vr);
    if (m->log) m->log(m->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

#define INSTANCE(c) Instance *m = (Instance *)(c); if (!m) return fmi3Error
#define CHECK(function, call) do { unsigned bad_ = 0; int code_ = (call); \
        if (code_ != CORE_OK) return failed(m, function, code_, bad_); } while (0)
#define ME_INSTANCE(c) INSTANCE(c); \
    if (m->type != ME) return failed(m, __func__, CORE_BAD_ARGUMENT, 0)
#define CS_INSTANCE(c) INSTANCE(c); \
    if (m->type != CS) return failed(m, __func__, CORE_BAD_ARGUMENT, 0)
#define UNSUPPORTED(c) INSTANCE(c); return failed(m, __func__, CORE_BAD_ARGUMENT, 0)

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n,
                               const fmi3String categories[]) {
    INSTANCE(c);
    (void)on; (void)n; (void)categories;
    return fmi3OK;
}

static Instance *instantiate(int type, fmi3String name, fmi3String token,
                             fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    Instance *m = calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->env = env;
    m->log = log;
    snprintf(m->name, sizeof(m->name), "%s", name ? name : "");
    if (!token || strcmp(token, MODEL_GUID) != 0) {
        if (log) log(env, fmi3Error, "logStatusError",
                     "fmi3Instantiate: the instantiationToken is not this FMU's");
        free(m);
        return NULL;
    }
    m->type = type;
    core_reset(&m->core, type == CS);
    return m;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)resources; (void)visible; (void)logging;
    return instantiate(ME, name, token, env, log);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
        const fmi3ValueReference required[], size_t nRequired,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
        fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resources; (void)visible; (void)logging; (void)earlyReturnAllowed;
    (void)required; (void)nRequired; (void)intermediateUpdate;
    (void)eventModeUsed;  /* hasEventMode="false": events are handled inside the step */
    return instantiate(CS, name, token, env, log);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
        fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lock,
        fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging;
    (void)clockUpdate; (void)lock; (void)unlock;
    if (log) log(env, fmi3Error, "logStatusError", "no scheduled execution");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolDefined,
                                       fmi3Float64 tol, fmi3Float64 start,
                                       fmi3Boolean stopDefined, fmi3Float64 stop) {
    INSTANCE(c);
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    core_enter_initialization(&m->core, start);
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    INSTANCE(c);
    core_exit_initialization(&m->core);
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    INSTANCE(c);
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    INSTANCE(c);
    m->core.phase = PHASE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    INSTANCE(c);
    core_reset(&m->core, m->type == CS);
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          fmi3Float64 values[], size_t nValues) {
    INSTANCE(c);
    if (nValues != n || (n > 0 && (!vr || !values)))
        return failed(m, "fmi3GetFloat64", CORE_BAD_ARGUMENT, (unsigned)nValues);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == TIME_VR) values[i] = m->core.d.time;
        else CHECK("fmi3GetFloat64", core_get_reals(&m->core, &vr[i], 1, &values[i], &bad_));
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          const fmi3Float64 values[], size_t nValues) {
    INSTANCE(c);
    if (nValues != n)
        return failed(m, "fmi3SetFloat64", CORE_BAD_ARGUMENT, (unsigned)nValues);
    CHECK("fmi3SetFloat64", core_set_reals(&m->core, vr, n, values, &bad_));
    return fmi3OK;
}

/* no variables of the other types: only empty calls succeed */
#define NONE_OF_TYPE(type, values_type) \
fmi3Status fmi3Get##type(fmi3Instance c, const fmi3ValueReference vr[], size_t n, \
                         values_type values[], size_t nValues) { \
    INSTANCE(c); (void)values; (void)nValues; \
    if (n == 0) return fmi3OK; \
    return failed(m, "fmi3Get" #type, CORE_UNKNOWN_VR, vr ? vr[0] : 0); \
} \
fmi3Status fmi3Set##type(fmi3Instance c, const fmi3ValueReference vr[], size_t n, \
                         const values_type values[], size_t nValues) { \
    INSTANCE(c); (void)values; (void)nValues; \
    if (n == 0) return fmi3OK; \
    return failed(m, "fmi3Set" #type, CORE_UNKNOWN_VR, vr ? vr[0] : 0); \
}
NONE_OF_TYPE(Float32, fmi3Float32)
NONE_OF_TYPE(Int8, fmi3Int8)
NONE_OF_TYPE(UInt8, fmi3UInt8)
NONE_OF_TYPE(Int16, fmi3Int16)
NONE_OF_TYPE(UInt16, fmi3UInt16)
NONE_OF_TYPE(Int32, fmi3Int32)
NONE_OF_TYPE(UInt32, fmi3UInt32)
#ifdef ENUM_VR
/* -DENUM_VR=<vr> -DENUM_OF=<a Real's vr>: one Enumeration output at ENUM_VR, the Real
 * at ENUM_OF rounded (FMI 3.0 reads and writes Enumerations with the Int64 functions) */
fmi3Status fmi3GetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3Int64 values[], size_t nValues) {
    INSTANCE(c);
    if (nValues != n || (n > 0 && (!vr || !values)))
        return failed(m, "fmi3GetInt64", CORE_BAD_ARGUMENT, (unsigned)nValues);
    for (size_t i = 0; i < n; i++) {
        const fmi3ValueReference of = ENUM_OF;
        double value;
        if (vr[i] != ENUM_VR) return failed(m, "fmi3GetInt64", CORE_UNKNOWN_VR, vr[i]);
        CHECK("fmi3GetInt64", core_get_reals(&m->core, &of, 1, &value, &bad_));
        values[i] = (fmi3Int64)llround(value);
    }
    return fmi3OK;
}
fmi3Status fmi3SetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3Int64 values[], size_t nValues) {
    INSTANCE(c); (void)values; (void)nValues;
    if (n == 0) return fmi3OK;
    return failed(m, "fmi3SetInt64", CORE_NOT_SETTABLE, vr ? vr[0] : 0);
}
#else
NONE_OF_TYPE(Int64, fmi3Int64)
#endif
NONE_OF_TYPE(UInt64, fmi3UInt64)
NONE_OF_TYPE(Boolean, fmi3Boolean)
NONE_OF_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         size_t sizes[], fmi3Binary values[], size_t nValues) {
    INSTANCE(c);
    (void)sizes; (void)values; (void)nValues;
    return n == 0 ? fmi3OK : failed(m, "fmi3GetBinary", CORE_UNKNOWN_VR, vr ? vr[0] : 0);
}

fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         const size_t sizes[], const fmi3Binary values[], size_t nValues) {
    INSTANCE(c);
    (void)sizes; (void)values; (void)nValues;
    return n == 0 ? fmi3OK : failed(m, "fmi3SetBinary", CORE_UNKNOWN_VR, vr ? vr[0] : 0);
}

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3Clock values[]) {
    INSTANCE(c);
    (void)values;
    return n == 0 ? fmi3OK : failed(m, "fmi3GetClock", CORE_UNKNOWN_VR, vr ? vr[0] : 0);
}

fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3Clock values[]) {
    INSTANCE(c);
    (void)values;
    return n == 0 ? fmi3OK : failed(m, "fmi3SetClock", CORE_UNKNOWN_VR, vr ? vr[0] : 0);
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr,
                                               size_t *n) {
    (void)vr; (void)n;
    UNSUPPORTED(c);
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dependent,
        size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
        size_t elementIndicesOfIndependents[], fmi3DependencyKind kinds[], size_t n) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents;
    (void)elementIndicesOfIndependents; (void)kinds; (void)n;
    UNSUPPORTED(c);
}

/* ---- FMU states: copies of the Core ---- */

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    return failed(m, "fmi3GetFMUState (not supported)", CORE_BAD_ARGUMENT, 0);
#else
    if (!state) return fmi3Error;
    if (!*state) *state = malloc(sizeof(Core));
    if (!*state) return fmi3Error;
    memcpy(*state, &m->core, sizeof(Core));
    return fmi3OK;
#endif
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    return failed(m, "fmi3SetFMUState (not supported)", CORE_BAD_ARGUMENT, 0);
#else
    if (!state) return fmi3Error;
    memcpy(&m->core, state, sizeof(Core));
    return fmi3OK;
#endif
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state;
    return fmi3Error;
#else
    if (!state) return fmi3Error;
    free(*state);
    *state = NULL;
    return fmi3OK;
#endif
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state; (void)size;
    return fmi3Error;
#else
    if (!state || !size) return fmi3Error;
    *size = sizeof(Core);
    return fmi3OK;
#endif
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[],
                                 size_t size) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)state; (void)bytes; (void)size;
    return fmi3Error;
#else
    if (!state || !bytes || size != sizeof(Core)) return fmi3Error;
    memcpy(bytes, state, sizeof(Core));
    return fmi3OK;
#endif
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size,
                                   fmi3FMUState *state) {
    INSTANCE(c);
#ifdef NO_STATE
    (void)bytes; (void)size; (void)state;
    return fmi3Error;
#else
    if (!bytes || !state || size != sizeof(Core)) return fmi3Error;
    if (!*state) *state = malloc(sizeof(Core));
    if (!*state) return fmi3Error;
    memcpy(*state, bytes, sizeof(Core));
    return fmi3OK;
#endif
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[],
        size_t nu, const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
        size_t ns, fmi3Float64 sensitivity[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sensitivity;
    (void)nsens;
    UNSUPPORTED(c);
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[],
        size_t nu, const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
        size_t ns, fmi3Float64 sensitivity[], size_t nsens) {
    (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sensitivity;
    (void)nsens;
    UNSUPPORTED(c);
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { UNSUPPORTED(c); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { UNSUPPORTED(c); }

/* no clocks */
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)n; (void)intervals; (void)qualifiers;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier q[]) {
    (void)vr; (void)n; (void)counters; (void)resolutions; (void)q;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3Float64 shifts[]) {
    (void)vr; (void)n; (void)shifts;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)n; (void)counters; (void)resolutions;
    UNSUPPORTED(c);
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3Float64 intervals[]) {
    (void)vr; (void)n; (void)intervals;
    UNSUPPORTED(c);
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)n; (void)counters; (void)resolutions;
    UNSUPPORTED(c);
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3Float64 shifts[]) {
    (void)vr; (void)n; (void)shifts;
    UNSUPPORTED(c);
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)n; (void)counters; (void)resolutions;
    UNSUPPORTED(c);
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference clock,
                                      fmi3Float64 time) {
    (void)clock; (void)time;
    UNSUPPORTED(c);
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
    INSTANCE(c);
    return fmi3OK;  /* nothing depends on discrete states but what model_event sets */
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *needUpdate,
        fmi3Boolean *terminate, fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
        fmi3Boolean *nextTimeDefined, fmi3Float64 *nextTime) {
    INSTANCE(c);
    int reinit = core_event_update(&m->core);
    int defined = isfinite(m->core.next_event);
    if (needUpdate) *needUpdate = fmi3False;
    if (terminate) *terminate = fmi3False;
    if (nominalsChanged) *nominalsChanged = fmi3False;
    if (valuesChanged) *valuesChanged = reinit ? fmi3True : fmi3False;
    if (nextTimeDefined) *nextTimeDefined = defined ? fmi3True : fmi3False;
    if (nextTime) *nextTime = defined ? m->core.next_event : 0.0;
    return fmi3OK;
}

/* ---- Model Exchange ---- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    ME_INSTANCE(c);
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetPrior,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminate) {
    ME_INSTANCE(c);
    (void)noSetPrior;
    if (!enterEventMode || !terminate) return fmi3Error;
    *enterEventMode = fmi3False;
    *terminate = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) {
    ME_INSTANCE(c);
    core_set_time(&m->core, time);
    return fmi3OK;
}

#define SIZED(function, n, expected, array) \
    if ((n) != (size_t)(expected) || ((n) > 0 && !(array))) \
        return failed(m, function, CORE_BAD_ARGUMENT, (unsigned)(n))

fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
    ME_INSTANCE(c);
    SIZED("fmi3SetContinuousStates", nx, model_n_states, x);
    core_set_states(&m->core, x);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    ME_INSTANCE(c);
    SIZED("fmi3GetContinuousStates", nx, model_n_states, x);
    core_get_states(&m->core, x);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
    ME_INSTANCE(c);
    SIZED("fmi3GetContinuousStateDerivatives", nx, model_n_states, dx);
    core_get_derivatives(&m->core, dx);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t nz) {
    ME_INSTANCE(c);
    SIZED("fmi3GetEventIndicators", nz, model_n_indicators, z);
    core_get_indicators(&m->core, z);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[],
                                             size_t nx) {
    ME_INSTANCE(c);
    SIZED("fmi3GetNominalsOfContinuousStates", nx, model_n_states, nominals);
    for (size_t i = 0; i < nx; i++) nominals[i] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    ME_INSTANCE(c);
    if (!n) return fmi3Error;
    *n = (size_t)model_n_indicators;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    ME_INSTANCE(c);
    if (!n) return fmi3Error;
    *n = (size_t)model_n_states;
    return fmi3OK;
}

/* ---- Co-Simulation ---- */

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    CS_INSTANCE(c);
    return fmi3OK;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    CS_INSTANCE(c);
    (void)orders; (void)values; (void)nValues;
    if (n == 0) return fmi3OK;
    return failed(m, "fmi3GetOutputDerivatives (maxOutputDerivativeOrder=0)",
                  CORE_BAD_ARGUMENT, vr ? vr[0] : 0);
}

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminate,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    CS_INSTANCE(c);
    (void)noSetPrior;
    if (m->core.phase != PHASE_RUNNING)
        return failed(m, "fmi3DoStep: not initialized", CORE_BAD_ARGUMENT, 0);
    CHECK("fmi3DoStep", core_do_step(&m->core, t, h));
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminate) *terminate = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = m->core.d.time;
    return fmi3OK;
}
