/* ABI check of libbacklash_fmu (run by `cargo xtask abi` with cc -fsyntax-only -Werror).
 *
 * The official FMI 2.0 header declares every fmi2 function with its standard type; the header
 * generated from the Rust sources declares them again from the Rust signatures. C accepts the
 * second declaration only if the two are compatible, so any difference in argument or return
 * types is a compile error here. */
#include "fmi2Functions.h"
#include "backlash_fmu.h"

/* The functions a Co-Simulation importer may call (FMI 2.0 §2.1 and §4.2), each assigned to the
 * standard's function-pointer type without a cast: a mismatch is an incompatible-pointer error. */
struct co_simulation_api {
    fmi2GetTypesPlatformTYPE *GetTypesPlatform;
    fmi2GetVersionTYPE *GetVersion;
    fmi2SetDebugLoggingTYPE *SetDebugLogging;
    fmi2InstantiateTYPE *Instantiate;
    fmi2FreeInstanceTYPE *FreeInstance;
    fmi2SetupExperimentTYPE *SetupExperiment;
    fmi2EnterInitializationModeTYPE *EnterInitializationMode;
    fmi2ExitInitializationModeTYPE *ExitInitializationMode;
    fmi2TerminateTYPE *Terminate;
    fmi2ResetTYPE *Reset;
    fmi2GetRealTYPE *GetReal;
    fmi2GetIntegerTYPE *GetInteger;
    fmi2GetBooleanTYPE *GetBoolean;
    fmi2GetStringTYPE *GetString;
    fmi2SetRealTYPE *SetReal;
    fmi2SetIntegerTYPE *SetInteger;
    fmi2SetBooleanTYPE *SetBoolean;
    fmi2SetStringTYPE *SetString;
    fmi2GetFMUstateTYPE *GetFMUstate;
    fmi2SetFMUstateTYPE *SetFMUstate;
    fmi2FreeFMUstateTYPE *FreeFMUstate;
    fmi2SerializedFMUstateSizeTYPE *SerializedFMUstateSize;
    fmi2SerializeFMUstateTYPE *SerializeFMUstate;
    fmi2DeSerializeFMUstateTYPE *DeSerializeFMUstate;
    fmi2GetDirectionalDerivativeTYPE *GetDirectionalDerivative;
    fmi2SetRealInputDerivativesTYPE *SetRealInputDerivatives;
    fmi2GetRealOutputDerivativesTYPE *GetRealOutputDerivatives;
    fmi2DoStepTYPE *DoStep;
    fmi2CancelStepTYPE *CancelStep;
    fmi2GetStatusTYPE *GetStatus;
    fmi2GetRealStatusTYPE *GetRealStatus;
    fmi2GetIntegerStatusTYPE *GetIntegerStatus;
    fmi2GetBooleanStatusTYPE *GetBooleanStatus;
    fmi2GetStringStatusTYPE *GetStringStatus;
};

const struct co_simulation_api backlash_fmu_api = {
    fmi2GetTypesPlatform,
    fmi2GetVersion,
    fmi2SetDebugLogging,
    fmi2Instantiate,
    fmi2FreeInstance,
    fmi2SetupExperiment,
    fmi2EnterInitializationMode,
    fmi2ExitInitializationMode,
    fmi2Terminate,
    fmi2Reset,
    fmi2GetReal,
    fmi2GetInteger,
    fmi2GetBoolean,
    fmi2GetString,
    fmi2SetReal,
    fmi2SetInteger,
    fmi2SetBoolean,
    fmi2SetString,
    fmi2GetFMUstate,
    fmi2SetFMUstate,
    fmi2FreeFMUstate,
    fmi2SerializedFMUstateSize,
    fmi2SerializeFMUstate,
    fmi2DeSerializeFMUstate,
    fmi2GetDirectionalDerivative,
    fmi2SetRealInputDerivatives,
    fmi2GetRealOutputDerivatives,
    fmi2DoStep,
    fmi2CancelStep,
    fmi2GetStatus,
    fmi2GetRealStatus,
    fmi2GetIntegerStatus,
    fmi2GetBooleanStatus,
    fmi2GetStringStatus,
};
