/* The FMI 1.0 Co-Simulation (stand-alone) skeleton of the models of this folder.
 * FMI 1.0 names its functions <modelIdentifier>_fmi<Name> (fmpy.fmi1 looks them up so):
 * FMI1_FUNCTION builds the names from -DMODEL_IDENTIFIER=<identifier>, and
 * fmi1Functions.h's function types check the signatures.  Only Real variables;
 * steps with core.c's RK4 integrator (events handled inside the step), inputs
 * interpolated linearly after fmiSetRealInputDerivatives (order 1).
 * Compile with -DMODEL_GUID='"{...}"' (the modelDescription.xml's guid). */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi1Functions.h"
#include "core.h"

#if !defined(MODEL_IDENTIFIER) || !defined(MODEL_GUID)
#error "compile with -DMODEL_IDENTIFIER=<identifier> -DMODEL_GUID=<guid>"
#endif

#define FMI1_PASTE(a, b) a##_##b
#define FMI1_NAME(a, b) FMI1_PASTE(a, b)
#define FMI1_FUNCTION(name) FMI1_NAME(MODEL_IDENTIFIER, name)
#define FMI1_Export __attribute__((visibility("default")))

/* the declarations (checked against the standard's function types) */
FMI1_Export fmi1GetTypesPlatformTYPE FMI1_FUNCTION(fmiGetTypesPlatform);
FMI1_Export fmi1GetVersionTYPE FMI1_FUNCTION(fmiGetVersion);
FMI1_Export fmi1SetDebugLoggingTYPE FMI1_FUNCTION(fmiSetDebugLogging);
FMI1_Export fmi1GetRealTYPE FMI1_FUNCTION(fmiGetReal);
FMI1_Export fmi1GetIntegerTYPE FMI1_FUNCTION(fmiGetInteger);
FMI1_Export fmi1GetBooleanTYPE FMI1_FUNCTION(fmiGetBoolean);
FMI1_Export fmi1GetStringTYPE FMI1_FUNCTION(fmiGetString);
FMI1_Export fmi1SetRealTYPE FMI1_FUNCTION(fmiSetReal);
FMI1_Export fmi1SetIntegerTYPE FMI1_FUNCTION(fmiSetInteger);
FMI1_Export fmi1SetBooleanTYPE FMI1_FUNCTION(fmiSetBoolean);
FMI1_Export fmi1SetStringTYPE FMI1_FUNCTION(fmiSetString);
FMI1_Export fmi1InstantiateSlaveTYPE FMI1_FUNCTION(fmiInstantiateSlave);
FMI1_Export fmi1InitializeSlaveTYPE FMI1_FUNCTION(fmiInitializeSlave);
FMI1_Export fmi1TerminateSlaveTYPE FMI1_FUNCTION(fmiTerminateSlave);
FMI1_Export fmi1ResetSlaveTYPE FMI1_FUNCTION(fmiResetSlave);
FMI1_Export fmi1FreeSlaveInstanceTYPE FMI1_FUNCTION(fmiFreeSlaveInstance);
FMI1_Export fmi1SetRealInputDerivativesTYPE FMI1_FUNCTION(fmiSetRealInputDerivatives);
FMI1_Export fmi1GetRealOutputDerivativesTYPE FMI1_FUNCTION(fmiGetRealOutputDerivatives);
FMI1_Export fmi1CancelStepTYPE FMI1_FUNCTION(fmiCancelStep);
FMI1_Export fmi1DoStepTYPE FMI1_FUNCTION(fmiDoStep);
FMI1_Export fmi1GetStatusTYPE FMI1_FUNCTION(fmiGetStatus);
FMI1_Export fmi1GetRealStatusTYPE FMI1_FUNCTION(fmiGetRealStatus);
FMI1_Export fmi1GetIntegerStatusTYPE FMI1_FUNCTION(fmiGetIntegerStatus);
FMI1_Export fmi1GetBooleanStatusTYPE FMI1_FUNCTION(fmiGetBooleanStatus);
FMI1_Export fmi1GetStringStatusTYPE FMI1_FUNCTION(fmiGetStringStatus);

typedef struct {
    Core core;
    char name[128];
    fmi1CallbackFunctions cb;
} Instance;

static fmi1Status failed(Instance *m, const char *function, int code, unsigned vr) {
    char message[256];
    const char *why = code == CORE_UNKNOWN_VR ? "unknown value reference"
                      : code == CORE_NOT_SETTABLE ? "variable not settable now"
                      : "bad argument";
    snprintf(message, sizeof(message), "%s: %s (%u)", function, why, vr);
    if (m->cb.logger) m->cb.logger(m, m->name, fmi1Error, "error", message);
    return fmi1Error;
}

#define INSTANCE(c) Instance *m = (Instance *)(c); if (!m) return fmi1Error
#define CHECK(function, call) do { unsigned bad_ = 0; int code_ = (call); \
        if (code_ != CORE_OK) return failed(m, function, code_, bad_); } while (0)

const char *FMI1_FUNCTION(fmiGetTypesPlatform)(void) { return "standard32"; }
const char *FMI1_FUNCTION(fmiGetVersion)(void) { return "1.0"; }

fmi1Status FMI1_FUNCTION(fmiSetDebugLogging)(fmi1Component c, fmi1Boolean on) {
    INSTANCE(c);
    (void)on;
    return fmi1OK;
}

fmi1Component FMI1_FUNCTION(fmiInstantiateSlave)(fmi1String name, fmi1String guid,
        fmi1String location, fmi1String mimeType, fmi1Real timeout, fmi1Boolean visible,
        fmi1Boolean interactive, fmi1CallbackFunctions functions, fmi1Boolean logging) {
    (void)location; (void)mimeType; (void)timeout; (void)visible; (void)interactive;
    (void)logging;
    Instance *m = calloc(1, sizeof(Instance));
    if (!m) return NULL;
    m->cb = functions;
    snprintf(m->name, sizeof(m->name), "%s", name ? name : "");
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        if (m->cb.logger)
            m->cb.logger(NULL, m->name, fmi1Error, "error",
                         "fmiInstantiateSlave: the GUID is not this FMU's");
        free(m);
        return NULL;
    }
    core_reset(&m->core, 1);
    return m;
}

fmi1Status FMI1_FUNCTION(fmiInitializeSlave)(fmi1Component c, fmi1Real tStart,
                                             fmi1Boolean stopDefined, fmi1Real tStop) {
    INSTANCE(c);
    (void)stopDefined; (void)tStop;
    core_enter_initialization(&m->core, tStart);
    core_exit_initialization(&m->core);
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiTerminateSlave)(fmi1Component c) {
    INSTANCE(c);
    m->core.phase = PHASE_TERMINATED;
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiResetSlave)(fmi1Component c) {
    INSTANCE(c);
    core_reset(&m->core, 1);
    return fmi1OK;
}

void FMI1_FUNCTION(fmiFreeSlaveInstance)(fmi1Component c) { free(c); }

fmi1Status FMI1_FUNCTION(fmiGetReal)(fmi1Component c, const fmi1ValueReference vr[],
                                     size_t n, fmi1Real value[]) {
    INSTANCE(c);
    CHECK("fmiGetReal", core_get_reals(&m->core, vr, n, value, &bad_));
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiSetReal)(fmi1Component c, const fmi1ValueReference vr[],
                                     size_t n, const fmi1Real value[]) {
    INSTANCE(c);
    CHECK("fmiSetReal", core_set_reals(&m->core, vr, n, value, &bad_));
    return fmi1OK;
}

/* no Integer, Boolean or String variables: only empty calls succeed */
#define NONE_OF_TYPE(function) \
    INSTANCE(c); (void)value; \
    if (n == 0) return fmi1OK; \
    return failed(m, function, CORE_UNKNOWN_VR, vr ? vr[0] : 0)

fmi1Status FMI1_FUNCTION(fmiGetInteger)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, fmi1Integer value[]) { NONE_OF_TYPE("fmiGetInteger"); }
fmi1Status FMI1_FUNCTION(fmiSetInteger)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, const fmi1Integer value[]) { NONE_OF_TYPE("fmiSetInteger"); }
fmi1Status FMI1_FUNCTION(fmiGetBoolean)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, fmi1Boolean value[]) { NONE_OF_TYPE("fmiGetBoolean"); }
fmi1Status FMI1_FUNCTION(fmiSetBoolean)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, const fmi1Boolean value[]) { NONE_OF_TYPE("fmiSetBoolean"); }
fmi1Status FMI1_FUNCTION(fmiGetString)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, fmi1String value[]) { NONE_OF_TYPE("fmiGetString"); }
fmi1Status FMI1_FUNCTION(fmiSetString)(fmi1Component c, const fmi1ValueReference vr[],
        size_t n, const fmi1String value[]) { NONE_OF_TYPE("fmiSetString"); }

fmi1Status FMI1_FUNCTION(fmiSetRealInputDerivatives)(fmi1Component c,
        const fmi1ValueReference vr[], size_t n, const fmi1Integer order[],
        const fmi1Real value[]) {
    INSTANCE(c);
    if (n > 0 && (!vr || !order || !value)) return fmi1Error;
    for (size_t i = 0; i < n; i++)
        CHECK("fmiSetRealInputDerivatives",
              core_set_input_derivative(&m->core, vr[i], order[i], value[i], &bad_));
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiGetRealOutputDerivatives)(fmi1Component c,
        const fmi1ValueReference vr[], size_t n, const fmi1Integer order[],
        fmi1Real value[]) {
    INSTANCE(c);
    (void)order; (void)value;
    if (n == 0) return fmi1OK;
    return failed(m, "fmiGetRealOutputDerivatives (maxOutputDerivativeOrder=0)",
                  CORE_BAD_ARGUMENT, vr ? vr[0] : 0);
}

fmi1Status FMI1_FUNCTION(fmiCancelStep)(fmi1Component c) {
    INSTANCE(c);
    return fmi1Error;  /* fmiDoStep never returns fmiPending */
}

fmi1Status FMI1_FUNCTION(fmiDoStep)(fmi1Component c, fmi1Real t, fmi1Real h,
                                    fmi1Boolean newStep) {
    INSTANCE(c);
    (void)newStep;
    if (m->core.phase != PHASE_RUNNING)
        return failed(m, "fmiDoStep: not initialized", CORE_BAD_ARGUMENT, 0);
    CHECK("fmiDoStep", core_do_step(&m->core, t, h));
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiGetStatus)(fmi1Component c, const fmi1StatusKind s,
                                       fmi1Status *value) {
    INSTANCE(c);
    if (s != fmi1DoStepStatus || !value) return fmi1Discard;
    *value = fmi1OK;
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiGetRealStatus)(fmi1Component c, const fmi1StatusKind s,
                                           fmi1Real *value) {
    INSTANCE(c);
    if (s != fmi1LastSuccessfulTime || !value) return fmi1Discard;
    *value = m->core.d.time;
    return fmi1OK;
}

fmi1Status FMI1_FUNCTION(fmiGetIntegerStatus)(fmi1Component c, const fmi1StatusKind s,
                                              fmi1Integer *value) {
    INSTANCE(c);
    (void)s; (void)value;
    return fmi1Discard;
}

fmi1Status FMI1_FUNCTION(fmiGetBooleanStatus)(fmi1Component c, const fmi1StatusKind s,
                                              fmi1Boolean *value) {
    INSTANCE(c);
    (void)s; (void)value;
    return fmi1Discard;
}

fmi1Status FMI1_FUNCTION(fmiGetStringStatus)(fmi1Component c, const fmi1StatusKind s,
                                             fmi1String *value) {
    INSTANCE(c);
    (void)s; (void)value;
    return fmi1Discard;
}
