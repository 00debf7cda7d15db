/* typed_array: a standalone FMI 3.0 Co-Simulation FMU (it uses neither core.c nor
 * model.h, which know scalar Float64 variables only) with what a master must handle
 * in FMI 3.0 beyond scalar Float64: arrays, Float32, Int32, Int64, UInt8, Boolean,
 * String and Enumeration variables.  build.py's build_typed_array writes its
 * modelDescription.xml (TYPED_ARRAY_VARIABLES there lists the same value references).
 *
 *   x_i' = -k_i x_i + gain8 u_i  (i = 0, 1, 2),  x(start) = (1, 1, 1),
 * integrated exactly by fmi3DoStep with u held over the step (c_i = gain8 u_i / k_i):
 *   x_i(t + h) = c_i + (x_i(t) - c_i) exp(-k_i h)    (k_i = 0: x_i + gain8 u_i h);
 *   x_sum = (float)(x_0 + x_1 + x_2),  positive = x_sum > 0,
 *   steps = (number of fmi3DoStep calls) + offset,  status = label ":" steps,
 *   mode = On (2) when some u_i != 0, else Off (1).
 *
 * The value reference of an array stands for all its elements: a getter or setter
 * must be given nValues = the sum of the sizes of its value references (else
 * fmi3Error).  Enumerations are got and set as Int64.  An FMU state is a copy of the
 * plain struct Data (the label is a fixed buffer); with -DNO_STATE the FMU-state
 * functions return fmi3Error.  Compile with -DMODEL_GUID='"{...}"' (the
 * instantiationToken, checked by fmi3InstantiateCoSimulation). */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

#ifndef MODEL_GUID
#error "compile with -DMODEL_GUID=<the instantiationToken of the modelDescription.xml>"
#endif

enum { VR_K = 1, VR_U, VR_X, VR_X_SUM, VR_STEPS, VR_OFFSET, VR_POSITIVE, VR_LABEL,
       VR_STATUS, VR_MODE, VR_GAIN8, VR_TIME = 1000 };
enum { F64, F32, I32, I64, U8, BOOL, STR, N_TYPES };  /* Enumeration: I64 */
enum { MODE_OFF = 1, MODE_ON = 2 };
enum { INSTANTIATED, INITIALIZATION, STEP, TERMINATED };
#define N 3
#define LABEL_SIZE 64

/* kind: 't' time, 'p' parameter (settable before the end of initialization),
 * 'i' input (settable at any time), 'o' output (never settable) */
typedef struct { unsigned vr; int type, size; char kind; } Variable;
static const Variable VARIABLES[] = {
    {VR_TIME, F64, 1, 't'}, {VR_K, F64, N, 'p'}, {VR_U, F64, N, 'i'},
    {VR_X, F64, N, 'o'}, {VR_X_SUM, F32, 1, 'o'}, {VR_STEPS, I32, 1, 'o'},
    {VR_OFFSET, I64, 1, 'p'}, {VR_POSITIVE, BOOL, 1, 'o'}, {VR_LABEL, STR, 1, 'p'},
    {VR_STATUS, STR, 1, 'o'}, {VR_MODE, I64, 1, 'o'}, {VR_GAIN8, U8, 1, 'i'},
};
#define N_VARIABLES (sizeof(VARIABLES) / sizeof(VARIABLES[0]))

typedef struct {  /* all the model's state: what an FMU state copies */
    int phase;
    double time, k[N], u[N], x[N];
    int64_t offset, count;  /* count: fmi3DoStep calls */
    uint8_t gain8;
    char label[LABEL_SIZE];
} Data;

typedef struct {
    Data d;
    char status[LABEL_SIZE + 24];  /* the last status got */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

static void start(Data *d) {  /* the modelDescription.xml's start values */
    memset(d, 0, sizeof(*d));
    for (int i = 0; i < N; i++) { d->k[i] = i + 1.0; d->u[i] = 0.0; d->x[i] = 1.0; }
    d->gain8 = 1;
    strcpy(d->label, "typed");
}

static float x_sum(const Data *d) { return (float)(d->x[0] + d->x[1] + d->x[2]); }
static int32_t steps(const Data *d) { return (int32_t)(d->count + d->offset); }
static int64_t mode(const Data *d) {
    for (int i = 0; i < N; i++) if (d->u[i] != 0.0) return MODE_ON;
    return MODE_OFF;
}

static fmi3Status error(Instance *m, const char *function, const char *format, ...) {
    char message[256];
    int used = snprintf(message, sizeof(message), "%s: ", function);
    va_list args;
    va_start(args, format);
    vsnprintf(message + used, sizeof(message) - (size_t)used, format, args);
    va_end(args);
    if (m->log) m->log(m->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

#define INSTANCE(c) Instance *m = (Instance *)(c); if (!m) return fmi3Error
#define UNSUPPORTED(c) INSTANCE(c); return error(m, __func__, "not supported")

/* every value reference is a variable of this type (settable now, for a setter) and
 * nValues is the sum of their sizes */
static fmi3Status check(Instance *m, const char *function, const fmi3ValueReference vr[],
                        size_t n, const void *values, size_t nValues, int type, int set) {
    size_t total = 0;
    if (n > 0 && (!vr || !values)) return error(m, function, "null argument");
    for (size_t i = 0; i < n; i++) {
        const Variable *v = NULL;
        for (size_t j = 0; j < N_VARIABLES; j++)
            if (VARIABLES[j].vr == vr[i] && VARIABLES[j].type == type) v = &VARIABLES[j];
        if (!v) return error(m, function, "unknown value reference %u", vr[i]);
        if (set && !(v->kind == 'i' || (v->kind == 'p' && m->d.phase < STEP)))
            return error(m, function, "variable %u is not settable now", vr[i]);
        total += (size_t)v->size;
    }
    if (total != nValues)
        return error(m, function, "nValues is %zu, the variables have %zu", nValues, total);
    return fmi3OK;
}

#define CHECK(type, set) do { fmi3Status s_ = check(m, __func__, vr, n, values, nValues, \
                                                    type, set); \
                              if (s_ != fmi3OK) return s_; } while (0)

/* ---- creation, modes ---- */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n,
                               const fmi3String categories[]) {
    INSTANCE(c);
    (void)on; (void)n; (void)categories;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
        const fmi3ValueReference required[], size_t nRequired,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
        fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)name; (void)resources; (void)visible; (void)logging; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)required; (void)nRequired; (void)intermediateUpdate;
    if (!token || strcmp(token, MODEL_GUID) != 0) {
        if (log) log(env, fmi3Error, "logStatusError",
                     "fmi3InstantiateCoSimulation: not this FMU's instantiationToken");
        return NULL;
    }
    Instance *m = calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->env = env;
    m->log = log;
    start(&m->d);
    return m;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging;
    if (log) log(env, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token,
        fmi3String resources, fmi3Boolean visible, fmi3Boolean logging,
        fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
        fmi3ClockUpdateCallback clockUpdate, fmi3LockPreemptionCallback lock,
        fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging;
    (void)clockUpdate; (void)lock; (void)unlock;
    if (log) log(env, fmi3Error, "logStatusError", "Co-Simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tolDefined,
                                       fmi3Float64 tol, fmi3Float64 startTime,
                                       fmi3Boolean stopDefined, fmi3Float64 stop) {
    INSTANCE(c);
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    if (m->d.phase != INSTANTIATED) return error(m, __func__, "not just instantiated");
    m->d.time = startTime;
    m->d.phase = INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    INSTANCE(c);
    if (m->d.phase != INITIALIZATION) return error(m, __func__, "not initializing");
    m->d.phase = STEP;  /* hasEventMode="false": straight to step mode */
    return fmi3OK;
}

fmi3Status fmi3EnterStepMode(fmi3Instance c) {
    INSTANCE(c);
    return m->d.phase == STEP ? fmi3OK : error(m, __func__, "not initialized");
}

fmi3Status fmi3Terminate(fmi3Instance c) {
    INSTANCE(c);
    m->d.phase = TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance c) {
    INSTANCE(c);
    start(&m->d);
    return fmi3OK;
}

/* ---- the step ---- */

fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminate,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    INSTANCE(c);
    (void)noSetPrior;
    Data *d = &m->d;
    if (d->phase != STEP) return error(m, __func__, "not in step mode");
    if (!(h > 0.0) || !isfinite(t + h)) return error(m, __func__, "bad step size %g", h);
    if (fabs(t - d->time) > 1e-9 * (1.0 + fabs(t)))
        return error(m, __func__, "the step starts at %.17g, the FMU is at %.17g", t,
                     d->time);
    for (int i = 0; i < N; i++) {
        double b = d->gain8 * d->u[i];  /* x' = -k x + b */
        if (d->k[i] == 0.0) d->x[i] += b * h;
        else d->x[i] = b / d->k[i] + (d->x[i] - b / d->k[i]) * exp(-d->k[i] * h);
    }
    d->time = t + h;
    d->count++;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminate) *terminate = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (lastSuccessfulTime) *lastSuccessfulTime = d->time;
    return fmi3OK;
}

/* ---- getters and setters ---- */

static void copy(double to[], const double from[], size_t *j, int count) {
    for (int e = 0; e < count; e++) to[(*j)++] = from[e];
}

fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          fmi3Float64 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(F64, 0);
    for (size_t i = 0, j = 0; i < n; i++) switch (vr[i]) {
        case VR_TIME: values[j++] = m->d.time; break;
        case VR_K: copy(values, m->d.k, &j, N); break;
        case VR_U: copy(values, m->d.u, &j, N); break;
        default: copy(values, m->d.x, &j, N); break;  /* VR_X */
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          const fmi3Float64 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(F64, 1);  /* the settable Float64 variables are k and u, both of size N */
    for (size_t i = 0, j = 0; i < n; i++, j += N)
        memcpy(vr[i] == VR_K ? m->d.k : m->d.u, &values[j], N * sizeof(double));
    return fmi3OK;
}

fmi3Status fmi3GetFloat32(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          fmi3Float32 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(F32, 0);
    for (size_t i = 0; i < n; i++) values[i] = x_sum(&m->d);
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3Int32 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(I32, 0);
    for (size_t i = 0; i < n; i++) values[i] = steps(&m->d);
    return fmi3OK;
}

fmi3Status fmi3GetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3Int64 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(I64, 0);
    for (size_t i = 0; i < n; i++)
        values[i] = vr[i] == VR_OFFSET ? m->d.offset : mode(&m->d);  /* or VR_MODE */
    return fmi3OK;
}

fmi3Status fmi3SetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3Int64 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(I64, 1);  /* only offset is settable */
    for (size_t i = 0; i < n; i++)
        if (values[i] < INT32_MIN || values[i] > INT32_MAX)
            return error(m, __func__, "offset %lld is not an Int32", (long long)values[i]);
    for (size_t i = 0; i < n; i++) m->d.offset = values[i];
    return fmi3OK;
}

fmi3Status fmi3GetUInt8(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3UInt8 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(U8, 0);
    for (size_t i = 0; i < n; i++) values[i] = m->d.gain8;
    return fmi3OK;
}

fmi3Status fmi3SetUInt8(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3UInt8 values[], size_t nValues) {
    INSTANCE(c);
    CHECK(U8, 1);
    for (size_t i = 0; i < n; i++) m->d.gain8 = values[i];
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          fmi3Boolean values[], size_t nValues) {
    INSTANCE(c);
    CHECK(BOOL, 0);
    for (size_t i = 0; i < n; i++) values[i] = x_sum(&m->d) > 0.0f ? fmi3True : fmi3False;
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         fmi3String values[], size_t nValues) {
    INSTANCE(c);
    CHECK(STR, 0);
    snprintf(m->status, sizeof(m->status), "%s:%ld", m->d.label, (long)steps(&m->d));
    for (size_t i = 0; i < n; i++) values[i] = vr[i] == VR_LABEL ? m->d.label : m->status;
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         const fmi3String values[], size_t nValues) {
    INSTANCE(c);
    CHECK(STR, 1);  /* only label is settable */
    for (size_t i = 0; i < n; i++)
        if (!values[i] || strlen(values[i]) >= LABEL_SIZE)
            return error(m, __func__, "the label is null or longer than %d bytes",
                         LABEL_SIZE - 1);
    for (size_t i = 0; i < n; i++) strcpy(m->d.label, values[i]);
    return fmi3OK;
}

/* the types without variables: only empty calls succeed */
#define NO_VARIABLES(type, T, set_const) \
fmi3Status fmi3Get##type(fmi3Instance c, const fmi3ValueReference vr[], size_t n, \
                         T values[], size_t nValues) { \
    INSTANCE(c); CHECK(N_TYPES, 0); return fmi3OK; \
} \
fmi3Status fmi3Set##type(fmi3Instance c, const fmi3ValueReference vr[], size_t n, \
                         set_const T values[], size_t nValues) { \
    INSTANCE(c); CHECK(N_TYPES, 1); return fmi3OK; \
}
NO_VARIABLES(Int8, fmi3Int8, const)
NO_VARIABLES(Int16, fmi3Int16, const)
NO_VARIABLES(UInt16, fmi3UInt16, const)
NO_VARIABLES(UInt32, fmi3UInt32, const)
NO_VARIABLES(UInt64, fmi3UInt64, const)

/* the read-only types: their setters fail for any variable */
fmi3Status fmi3SetFloat32(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          const fmi3Float32 values[], size_t nValues) {
    INSTANCE(c); CHECK(F32, 1); return fmi3OK;
}
fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3Int32 values[], size_t nValues) {
    INSTANCE(c); CHECK(I32, 1); return fmi3OK;
}
fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                          const fmi3Boolean values[], size_t nValues) {
    INSTANCE(c); CHECK(BOOL, 1); return fmi3OK;
}

fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         size_t sizes[], fmi3Binary values[], size_t nValues) {
    INSTANCE(c); (void)sizes; CHECK(N_TYPES, 0); return fmi3OK;
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                         const size_t sizes[], const fmi3Binary values[], size_t nValues) {
    INSTANCE(c); (void)sizes; CHECK(N_TYPES, 1); return fmi3OK;
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        fmi3Clock values[]) {
    INSTANCE(c); size_t nValues = n; CHECK(N_TYPES, 0); return fmi3OK;
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
                        const fmi3Clock values[]) {
    INSTANCE(c); size_t nValues = n; CHECK(N_TYPES, 1); return fmi3OK;
}

/* ---- FMU states: copies of Data ---- */

#ifdef NO_STATE
#define STATE_FUNCTION(c) UNSUPPORTED(c)
#else
#define STATE_FUNCTION(c) INSTANCE(c)
#endif

fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *state) {
    STATE_FUNCTION(c);
    if (!state) return error(m, __func__, "null argument");
    if (!*state) *state = malloc(sizeof(Data));
    if (!*state) return error(m, __func__, "out of memory");
    memcpy(*state, &m->d, sizeof(Data));
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState state) {
    STATE_FUNCTION(c);
    if (!state) return error(m, __func__, "null argument");
    memcpy(&m->d, state, sizeof(Data));
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *state) {
    STATE_FUNCTION(c);
    if (!state) return error(m, __func__, "null argument");
    free(*state);
    *state = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState state, size_t *size) {
    STATE_FUNCTION(c);
    if (!state || !size) return error(m, __func__, "null argument");
    *size = sizeof(Data);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState state, fmi3Byte bytes[],
                                 size_t size) {
    STATE_FUNCTION(c);
    if (!state || !bytes || size != sizeof(Data)) return error(m, __func__, "bad argument");
    memcpy(bytes, state, sizeof(Data));
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte bytes[], size_t size,
                                   fmi3FMUState *state) {
    STATE_FUNCTION(c);
    if (!bytes || !state || size != sizeof(Data)) return error(m, __func__, "bad argument");
    if (!*state) *state = malloc(sizeof(Data));
    if (!*state) return error(m, __func__, "out of memory");
    memcpy(*state, bytes, sizeof(Data));
    return fmi3OK;
}

/* ---- what this FMU does not provide: fmi3Error (but for empty calls) ---- */

fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t n,
        const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    INSTANCE(c);
    (void)vr; (void)orders; (void)values; (void)nValues;
    return n == 0 ? fmi3OK : error(m, __func__, "maxOutputDerivativeOrder is 0");
}

fmi3Status fmi3EnterEventMode(fmi3Instance c) { UNSUPPORTED(c); }  /* hasEventMode=false */
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { UNSUPPORTED(c); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *needUpdate,
        fmi3Boolean *terminate, fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
        fmi3Boolean *nextTimeDefined, fmi3Float64 *nextTime) {
    (void)needUpdate; (void)terminate; (void)nominalsChanged; (void)valuesChanged;
    (void)nextTimeDefined; (void)nextTime;
    UNSUPPORTED(c);
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { UNSUPPORTED(c); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { UNSUPPORTED(c); }

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

/* Model Exchange (fmpy binds these too: they must exist) */
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { UNSUPPORTED(c); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean noSetPrior,
        fmi3Boolean *enterEventMode, fmi3Boolean *terminate) {
    (void)noSetPrior; (void)enterEventMode; (void)terminate;
    UNSUPPORTED(c);
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 time) { (void)time; UNSUPPORTED(c); }
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
    (void)x; (void)nx;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    (void)x; (void)nx;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
    (void)dx; (void)nx;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t nz) {
    (void)z; (void)nz;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 nominals[],
                                             size_t nx) {
    (void)nominals; (void)nx;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)n;
    UNSUPPORTED(c);
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)n;
    UNSUPPORTED(c);
}
