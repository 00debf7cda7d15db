/* A driver linked with one FMU (a skeleton, core.c and a model) that runs it through
 * its FMI API the way importers do: both interfaces, events, FMU states (get, set,
 * serialize, free), inputs and their slopes, and the calls that must fail (null
 * instance, unknown value reference, wrong guid, non-settable variable).  The tests
 * compile it with -fsanitize=address,undefined -DFMI_VERSION=1|2|3: an out-of-bounds
 * access, a leak or undefined behaviour makes it fail, and so does an unexpected
 * status (it prints which and exits with 1). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "model.h"

static int failures = 0;
#define EXPECT(cond) do { if (!(cond)) { \
    fprintf(stderr, "memcheck: %s:%d: %s\n", __FILE__, __LINE__, #cond); failures++; } \
    } while (0)

static unsigned inputs[MAX_VARS], all[MAX_VARS];
static int n_inputs = 0;

static void list_variables(void) {
    for (int i = 0; i < model_n_vars; i++) {
        all[i] = (unsigned)i;
        if (model_kinds[i] == 'i') inputs[n_inputs++] = (unsigned)i;
    }
}

static unsigned computed_vr(void) {  /* a variable that must not be settable */
    for (int i = 0; i < model_n_vars; i++) if (model_kinds[i] == 'c') return (unsigned)i;
    return 0;
}

#if FMI_VERSION == 2
#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env; (void)name; (void)status; (void)category; (void)message;
}

static void run(void) {
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    double values[MAX_VARS], slopes[MAX_VARS], x[MAX_STATES], dx[MAX_STATES];
    double z[MAX_INDICATORS], z_before[MAX_INDICATORS], one = 1.0;
    fmi2Integer orders[MAX_VARS];
    unsigned bad = 99999, c_vr = computed_vr();

    EXPECT(fmi2Instantiate("x", fmi2CoSimulation, "{wrong}", "", &cb, 0, 0) == NULL);
    EXPECT(fmi2GetReal(NULL, all, 1, values) == fmi2Error);
    EXPECT(fmi2DoStep(NULL, 0.0, 0.1, 1) == fmi2Error);

    /* co-simulation */
    fmi2Component c = fmi2Instantiate("cs", fmi2CoSimulation, MODEL_GUID, "", &cb, 0, 0);
    EXPECT(c != NULL);
    EXPECT(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == fmi2OK);
    EXPECT(fmi2EnterInitializationMode(c) == fmi2OK);
    EXPECT(fmi2GetReal(c, all, (size_t)model_n_vars, values) == fmi2OK);
    EXPECT(fmi2ExitInitializationMode(c) == fmi2OK);
    EXPECT(fmi2GetReal(c, &bad, 1, values) == fmi2Error);
    EXPECT(fmi2SetReal(c, &bad, 1, &one) == fmi2Error);
    EXPECT(fmi2SetReal(c, &c_vr, 1, &one) == fmi2Error);
    EXPECT(fmi2GetInteger(c, NULL, 0, NULL) == fmi2OK);
    EXPECT(fmi2GetBoolean(c, NULL, 0, NULL) == fmi2OK);
    EXPECT(fmi2GetString(c, NULL, 0, NULL) == fmi2OK);
    EXPECT(fmi2GetInteger(c, all, 1, (fmi2Integer *)values) == fmi2Error);
    fmi2FMUstate state = NULL, copy = NULL;
    for (int step = 0; step < 300; step++) {
        double t = 0.01 * step;
        for (int i = 0; i < n_inputs; i++) {
            values[i] = 0.1 * i + 0.01; slopes[i] = 0.5; orders[i] = 1;
        }
        EXPECT(fmi2SetReal(c, inputs, (size_t)n_inputs, values) == fmi2OK);
        EXPECT(fmi2SetRealInputDerivatives(c, inputs, (size_t)n_inputs, orders, slopes)
               == fmi2OK);
#ifdef NO_STATE
        if (step == 100) EXPECT(fmi2GetFMUstate(c, &state) == fmi2Error && !state);
#else
        if (step == 100) EXPECT(fmi2GetFMUstate(c, &state) == fmi2OK);
#endif
        EXPECT(fmi2DoStep(c, t, 0.01, 1) == fmi2OK);
        EXPECT(fmi2GetReal(c, all, (size_t)model_n_vars, values) == fmi2OK);
    }
    EXPECT(fmi2DoStep(c, 3.0, -1.0, 1) == fmi2Error);
    if (state) {
        size_t size = 0;
        EXPECT(fmi2SetFMUstate(c, state) == fmi2OK);
        EXPECT(fmi2GetFMUstate(c, &state) == fmi2OK);  /* reuses the copy */
        EXPECT(fmi2SerializedFMUstateSize(c, state, &size) == fmi2OK);
        fmi2Byte *bytes = malloc(size);
        EXPECT(fmi2SerializeFMUstate(c, state, bytes, size) == fmi2OK);
        EXPECT(fmi2DeSerializeFMUstate(c, bytes, size, &copy) == fmi2OK);
        EXPECT(fmi2SetFMUstate(c, copy) == fmi2OK);
        free(bytes);
        EXPECT(fmi2FreeFMUstate(c, &copy) == fmi2OK && copy == NULL);
        EXPECT(fmi2FreeFMUstate(c, &state) == fmi2OK && state == NULL);
    }
    EXPECT(fmi2Terminate(c) == fmi2OK);
    EXPECT(fmi2Reset(c) == fmi2OK);
    fmi2FreeInstance(c);

    /* model exchange: explicit Euler with event handling */
    c = fmi2Instantiate("me", fmi2ModelExchange, MODEL_GUID, "", &cb, 0, 0);
    EXPECT(c != NULL);
    EXPECT(fmi2DoStep(c, 0.0, 0.1, 1) == fmi2Error);  /* not a co-simulation */
    fmi2EventInfo info;
    fmi2Boolean enter = 0, terminate = 0;
    EXPECT(fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) == fmi2OK);
    EXPECT(fmi2EnterInitializationMode(c) == fmi2OK);
    EXPECT(fmi2ExitInitializationMode(c) == fmi2OK);
    EXPECT(fmi2NewDiscreteStates(c, &info) == fmi2OK);
    EXPECT(fmi2EnterContinuousTimeMode(c) == fmi2OK);
    size_t nx = (size_t)model_n_states, nz = (size_t)model_n_indicators;
    EXPECT(fmi2GetEventIndicators(c, z_before, nz) == fmi2OK);
    EXPECT(fmi2GetContinuousStates(c, x, nx + 1) == fmi2Error);
    for (int step = 0; step < 3000; step++) {
        double t = 1e-3 * (step + 1);
        EXPECT(fmi2GetContinuousStates(c, x, nx) == fmi2OK);
        EXPECT(fmi2GetDerivatives(c, dx, nx) == fmi2OK);
        EXPECT(fmi2GetNominalsOfContinuousStates(c, dx, nx) == fmi2OK);
        EXPECT(fmi2GetDerivatives(c, dx, nx) == fmi2OK);
        for (size_t i = 0; i < nx; i++) x[i] += 1e-3 * dx[i];
        EXPECT(fmi2SetTime(c, t) == fmi2OK);
        EXPECT(fmi2SetContinuousStates(c, x, nx) == fmi2OK);
        EXPECT(fmi2CompletedIntegratorStep(c, 1, &enter, &terminate) == fmi2OK);
        EXPECT(fmi2GetEventIndicators(c, z, nz) == fmi2OK);
        int event = info.nextEventTimeDefined && t >= info.nextEventTime;
        for (size_t i = 0; i < nz; i++) event |= (z_before[i] > 0) != (z[i] > 0);
        if (event) {
            EXPECT(fmi2EnterEventMode(c) == fmi2OK);
            EXPECT(fmi2NewDiscreteStates(c, &info) == fmi2OK);
            EXPECT(fmi2EnterContinuousTimeMode(c) == fmi2OK);
            EXPECT(fmi2GetEventIndicators(c, z, nz) == fmi2OK);
        }
        memcpy(z_before, z, sizeof(z));
        EXPECT(fmi2GetReal(c, all, (size_t)model_n_vars, values) == fmi2OK);
    }
    EXPECT(fmi2Terminate(c) == fmi2OK);
    fmi2FreeInstance(c);
}

#elif FMI_VERSION == 3
#include "fmi3Functions.h"

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                   fmi3String message) {
    (void)env; (void)status; (void)category; (void)message;
}

static void run(void) {
    double values[MAX_VARS], x[MAX_STATES], dx[MAX_STATES], z[MAX_INDICATORS];
    double z_before[MAX_INDICATORS], one = 1.0, next = 0.0;
    unsigned bad = 99999, c_vr = computed_vr(), time_vr = TIME_VR;
    fmi3Boolean update, terminate, nominals, changed, defined, event_needed, early;
    fmi3Boolean enter;

    EXPECT(fmi3InstantiateCoSimulation("x", "{wrong}", "", 0, 0, 0, 0, NULL, 0, NULL,
                                       logger, NULL) == NULL);
    EXPECT(fmi3GetFloat64(NULL, all, 1, values, 1) == fmi3Error);

    fmi3Instance c = fmi3InstantiateCoSimulation("cs", MODEL_GUID, "", 0, 0, 0, 0, NULL,
                                                 0, NULL, logger, NULL);
    EXPECT(c != NULL);
    EXPECT(fmi3EnterInitializationMode(c, 0, 0.0, 0.0, 0, 0.0) == fmi3OK);
    EXPECT(fmi3ExitInitializationMode(c) == fmi3OK);
    EXPECT(fmi3GetFloat64(c, &bad, 1, values, 1) == fmi3Error);
    EXPECT(fmi3SetFloat64(c, &c_vr, 1, &one, 1) == fmi3Error);
    EXPECT(fmi3GetInt32(c, NULL, 0, NULL, 0) == fmi3OK);
    EXPECT(fmi3GetString(c, NULL, 0, NULL, 0) == fmi3OK);
    EXPECT(fmi3GetBoolean(c, all, 1, (fmi3Boolean *)values, 1) == fmi3Error);
    fmi3FMUState state = NULL, copy = NULL;
    for (int step = 0; step < 300; step++) {
        double t = 0.01 * step, last = 0.0;
        for (int i = 0; i < n_inputs; i++) values[i] = 0.1 * i + 0.01;
        EXPECT(fmi3SetFloat64(c, inputs, (size_t)n_inputs, values, (size_t)n_inputs)
               == fmi3OK);
#ifdef NO_STATE
        if (step == 100) EXPECT(fmi3GetFMUState(c, &state) == fmi3Error && !state);
#else
        if (step == 100) EXPECT(fmi3GetFMUState(c, &state) == fmi3OK);
#endif
        EXPECT(fmi3DoStep(c, t, 0.01, 1, &event_needed, &terminate, &early, &last)
               == fmi3OK);
        EXPECT(!event_needed && !terminate && !early && last == t + 0.01);
        EXPECT(fmi3GetFloat64(c, all, (size_t)model_n_vars, values, (size_t)model_n_vars)
               == fmi3OK);
        EXPECT(fmi3GetFloat64(c, &time_vr, 1, values, 1) == fmi3OK && values[0] == t + 0.01);
    }
    if (state) {
        size_t size = 0;
        EXPECT(fmi3SetFMUState(c, state) == fmi3OK);
        EXPECT(fmi3SerializedFMUStateSize(c, state, &size) == fmi3OK);
        fmi3Byte *bytes = malloc(size);
        EXPECT(fmi3SerializeFMUState(c, state, bytes, size) == fmi3OK);
        EXPECT(fmi3DeserializeFMUState(c, bytes, size, &copy) == fmi3OK);
        free(bytes);
        EXPECT(fmi3FreeFMUState(c, &copy) == fmi3OK && copy == NULL);
        EXPECT(fmi3FreeFMUState(c, &state) == fmi3OK && state == NULL);
    }
    EXPECT(fmi3Terminate(c) == fmi3OK);
    fmi3FreeInstance(c);

    c = fmi3InstantiateModelExchange("me", MODEL_GUID, "", 0, 0, NULL, logger);
    EXPECT(c != NULL);
    EXPECT(fmi3EnterInitializationMode(c, 0, 0.0, 0.0, 0, 0.0) == fmi3OK);
    EXPECT(fmi3ExitInitializationMode(c) == fmi3OK);
    EXPECT(fmi3UpdateDiscreteStates(c, &update, &terminate, &nominals, &changed, &defined,
                                    &next) == fmi3OK);
    EXPECT(fmi3EnterContinuousTimeMode(c) == fmi3OK);
    size_t nx = (size_t)model_n_states, nz = (size_t)model_n_indicators, n = 0;
    EXPECT(fmi3GetNumberOfContinuousStates(c, &n) == fmi3OK && n == nx);
    EXPECT(fmi3GetNumberOfEventIndicators(c, &n) == fmi3OK && n == nz);
    EXPECT(fmi3GetEventIndicators(c, z_before, nz) == fmi3OK);
    for (int step = 0; step < 3000; step++) {
        double t = 1e-3 * (step + 1);
        EXPECT(fmi3GetContinuousStates(c, x, nx) == fmi3OK);
        EXPECT(fmi3GetContinuousStateDerivatives(c, dx, nx) == fmi3OK);
        for (size_t i = 0; i < nx; i++) x[i] += 1e-3 * dx[i];
        EXPECT(fmi3SetTime(c, t) == fmi3OK);
        EXPECT(fmi3SetContinuousStates(c, x, nx) == fmi3OK);
        EXPECT(fmi3CompletedIntegratorStep(c, 1, &enter, &terminate) == fmi3OK);
        EXPECT(fmi3GetEventIndicators(c, z, nz) == fmi3OK);
        int event = defined && t >= next;
        for (size_t i = 0; i < nz; i++) event |= (z_before[i] > 0) != (z[i] > 0);
        if (event) {
            EXPECT(fmi3EnterEventMode(c) == fmi3OK);
            EXPECT(fmi3UpdateDiscreteStates(c, &update, &terminate, &nominals, &changed,
                                            &defined, &next) == fmi3OK);
            EXPECT(fmi3EnterContinuousTimeMode(c) == fmi3OK);
            EXPECT(fmi3GetEventIndicators(c, z, nz) == fmi3OK);
        }
        memcpy(z_before, z, sizeof(z));
    }
    EXPECT(fmi3Terminate(c) == fmi3OK);
    fmi3FreeInstance(c);
}

#elif FMI_VERSION == 1
#include "fmi1Functions.h"
#define PASTE(a, b) a##_##b
#define NAME(a, b) PASTE(a, b)
#define F(name) NAME(MODEL_IDENTIFIER, name)
fmi1InstantiateSlaveTYPE F(fmiInstantiateSlave);
fmi1InitializeSlaveTYPE F(fmiInitializeSlave);
fmi1DoStepTYPE F(fmiDoStep);
fmi1GetRealTYPE F(fmiGetReal);
fmi1SetRealTYPE F(fmiSetReal);
fmi1GetIntegerTYPE F(fmiGetInteger);
fmi1SetRealInputDerivativesTYPE F(fmiSetRealInputDerivatives);
fmi1TerminateSlaveTYPE F(fmiTerminateSlave);
fmi1ResetSlaveTYPE F(fmiResetSlave);
fmi1FreeSlaveInstanceTYPE F(fmiFreeSlaveInstance);
fmi1GetRealStatusTYPE F(fmiGetRealStatus);

static void logger(fmi1Component c, fmi1String name, fmi1Status status,
                   fmi1String category, fmi1String message, ...) {
    (void)c; (void)name; (void)status; (void)category; (void)message;
}

static void run(void) {
    fmi1CallbackFunctions cb = {logger, calloc, free, NULL};
    double values[MAX_VARS], slopes[MAX_VARS], one = 1.0, last = 0.0;
    fmi1Integer orders[MAX_VARS];
    unsigned bad = 99999, c_vr = computed_vr();

    EXPECT(F(fmiInstantiateSlave)("x", "{wrong}", "", "", 0.0, 0, 0, cb, 0) == NULL);
    EXPECT(F(fmiGetReal)(NULL, all, 1, values) == fmi1Error);
    fmi1Component c = F(fmiInstantiateSlave)("cs", MODEL_GUID, "", "", 0.0, 0, 0, cb, 0);
    EXPECT(c != NULL);
    EXPECT(F(fmiInitializeSlave)(c, 0.0, 0, 0.0) == fmi1OK);
    EXPECT(F(fmiGetReal)(c, &bad, 1, values) == fmi1Error);
    EXPECT(F(fmiSetReal)(c, &c_vr, 1, &one) == fmi1Error);
    EXPECT(F(fmiGetInteger)(c, NULL, 0, NULL) == fmi1OK);
    for (int step = 0; step < 300; step++) {
        for (int i = 0; i < n_inputs; i++) {
            values[i] = 0.1 * i + 0.01; slopes[i] = 0.5; orders[i] = 1;
        }
        EXPECT(F(fmiSetReal)(c, inputs, (size_t)n_inputs, values) == fmi1OK);
        EXPECT(F(fmiSetRealInputDerivatives)(c, inputs, (size_t)n_inputs, orders, slopes)
               == fmi1OK);
        EXPECT(F(fmiDoStep)(c, 0.01 * step, 0.01, 1) == fmi1OK);
        EXPECT(F(fmiGetReal)(c, all, (size_t)model_n_vars, values) == fmi1OK);
    }
    EXPECT(F(fmiGetRealStatus)(c, fmi1LastSuccessfulTime, &last) == fmi1OK && last > 2.99);
    EXPECT(F(fmiTerminateSlave)(c) == fmi1OK);
    EXPECT(F(fmiResetSlave)(c) == fmi1OK);
    F(fmiFreeSlaveInstance)(c);
}
#else
#error "compile with -DFMI_VERSION=1, 2 or 3"
#endif

int main(void) {
    list_variables();
    run();
    if (failures) fprintf(stderr, "memcheck: %d failed expectations\n", failures);
    return failures ? 1 : 0;
}
