/* Instantiate/free cycles through the C ABI of a packaged FMU, for scripts/leak_check.sh.
 *
 * Usage: leak_driver <model .so> <guid> <cycles> <vr of tau_m> <vr of omega_m> <continuous states>
 *        <event indicators>
 *
 * Each cycle, for Co-Simulation: fmi2Instantiate, a refused call (NULL array) and recovery by
 * fmi2Reset, setup, initialization, 5 steps, an FMU state serialized and deserialized (freed
 * explicitly), one more FMU state left for fmi2FreeInstance to free, and fmi2FreeInstance. Then
 * the same for Model Exchange: a refused call and fmi2Reset, initialization, the event
 * iteration, 5 explicit Euler steps through fmi2SetTime, fmi2SetContinuousStates,
 * fmi2GetDerivatives, fmi2GetEventIndicators and fmi2CompletedIntegratorStep, an FMU state
 * serialized, deserialized and set, one left for fmi2FreeInstance, and fmi2FreeInstance. Every
 * status is checked, so a leak check never passes on a run that did nothing.
 *
 * A controller (no continuous state: BacklashController, whose tau_m is its output and omega_m
 * its input) serves Co-Simulation only: each cycle a refused call and fmi2Reset, initialization,
 * 5 samples, its torque read, a refused fmi2GetFMUstate (it has no FMU state) and
 * fmi2FreeInstance, then a refused Model Exchange instantiation.
 *
 * Without valgrind the driver also measures the heap (mallinfo2) after a warm-up of a tenth of
 * the cycles and at the end, and fails if it grew by more than GROWTH_LIMIT bytes. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <malloc.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define GROWTH_LIMIT 4096
#define MAX_STATES 8
#define MAX_INDICATORS 32

static int logged = 0;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env, (void)name, (void)status, (void)category, (void)message;
    logged++;
}

#define LOAD(f)                                                               \
    f##TYPE *f = (f##TYPE *)dlsym(lib, #f);                                   \
    if (!f) {                                                                 \
        fprintf(stderr, "missing symbol %s\n", #f);                           \
        return 2;                                                             \
    }

#define CHECK(call, expected)                                                 \
    do {                                                                      \
        fmi2Status s_ = (call);                                               \
        if (s_ != (expected)) {                                               \
            fprintf(stderr, "cycle %ld: %s returned %d\n", k, #call, (int)s_); \
            return 1;                                                         \
        }                                                                     \
    } while (0)

int main(int argc, char **argv) {
    if (argc != 8) {
        fprintf(stderr,
                "usage: %s <model .so> <guid> <cycles> <vr of tau_m> <vr of omega_m> <continuous states> "
                "<event indicators>\n",
                argv[0]);
        return 2;
    }
    long cycles = atol(argv[3]);
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "%s\n", dlerror());
        return 2;
    }
    LOAD(fmi2Instantiate) LOAD(fmi2FreeInstance) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2Reset) LOAD(fmi2DoStep) LOAD(fmi2SetReal) LOAD(fmi2GetReal)
    LOAD(fmi2GetFMUstate) LOAD(fmi2FreeFMUstate) LOAD(fmi2SerializedFMUstateSize) LOAD(fmi2SerializeFMUstate)
    LOAD(fmi2DeSerializeFMUstate) LOAD(fmi2SetFMUstate) LOAD(fmi2NewDiscreteStates) LOAD(fmi2EnterContinuousTimeMode)
    LOAD(fmi2EnterEventMode) LOAD(fmi2SetTime) LOAD(fmi2SetContinuousStates) LOAD(fmi2GetContinuousStates)
    LOAD(fmi2GetDerivatives) LOAD(fmi2GetEventIndicators) LOAD(fmi2CompletedIntegratorStep)

    fmi2CallbackFunctions cb = {logger, NULL, NULL, NULL, NULL};
    const fmi2ValueReference tau_m = (fmi2ValueReference)atol(argv[4]), omega_m = (fmi2ValueReference)atol(argv[5]);
    /* 4, or 5 with a web span's tension. */
    const size_t nx = (size_t)atol(argv[6]);
    if (nx > MAX_STATES) {
        fprintf(stderr, "%zu continuous states: expected at most %d\n", nx, MAX_STATES);
        return 2;
    }
    /* numberOfEventIndicators of the model description. */
    const size_t nz = (size_t)atol(argv[7]);
    if (nz > MAX_INDICATORS) {
        fprintf(stderr, "%zu event indicators: expected at most %d\n", nz, MAX_INDICATORS);
        return 2;
    }
    size_t heap_after_warmup = 0;
    for (long k = 0; k < cycles; k++) {
        if (k == cycles / 10) heap_after_warmup = mallinfo2().uordblks;
        fmi2Component c = fmi2Instantiate("leak check", fmi2CoSimulation, argv[2], "file:///tmp/a%20b", &cb,
                                          fmi2False, fmi2False);
        if (!c) {
            fprintf(stderr, "cycle %ld: fmi2Instantiate returned NULL\n", k);
            return 1;
        }
        /* A controller's tau_m is its output: the refused call sets its input omega_m instead. */
        CHECK(fmi2SetReal(c, nx ? &tau_m : &omega_m, 1, NULL), fmi2Error);
        CHECK(fmi2Reset(c), fmi2OK);
        CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
        CHECK(fmi2EnterInitializationMode(c), fmi2OK);
        if (nx == 0) {
            /* A controller: from rest, 5 samples of its default experiment's step, 1 ms. */
            CHECK(fmi2ExitInitializationMode(c), fmi2OK);
            fmi2Real w = 0.01 * (1 + k % 7), u = 0.0;
            CHECK(fmi2SetReal(c, &omega_m, 1, &w), fmi2OK);
            for (int i = 0; i < 5; i++) CHECK(fmi2DoStep(c, i * 1e-3, 1e-3, fmi2True), fmi2OK);
            CHECK(fmi2GetReal(c, &tau_m, 1, &u), fmi2OK);
            if (!(u < 0.0)) {
                fprintf(stderr, "cycle %ld: tau_m = %g after 5 samples of omega_m = %g from rest\n", k, u, w);
                return 1;
            }
            fmi2FMUstate none = NULL;
            CHECK(fmi2GetFMUstate(c, &none), fmi2Error);
            fmi2FreeInstance(c);
            if (fmi2Instantiate("leak check ME", fmi2ModelExchange, argv[2], "file:///tmp/a%20b", &cb, fmi2False,
                                fmi2False)) {
                fprintf(stderr, "cycle %ld: a controller was instantiated for Model Exchange\n", k);
                return 1;
            }
            continue;
        }
        fmi2Real tau = 1.0 + (k % 7);
        CHECK(fmi2SetReal(c, &tau_m, 1, &tau), fmi2OK);
        CHECK(fmi2ExitInitializationMode(c), fmi2OK);
        for (int i = 0; i < 5; i++) CHECK(fmi2DoStep(c, i * 1e-3, 1e-3, fmi2True), fmi2OK);
        fmi2Real w = 0.0;
        CHECK(fmi2GetReal(c, &omega_m, 1, &w), fmi2OK);
        if (!(w > 0.0)) {
            fprintf(stderr, "cycle %ld: omega_m = %g\n", k, w);
            return 1;
        }
        fmi2FMUstate state = NULL, copy = NULL, kept = NULL;
        size_t size = 0;
        CHECK(fmi2GetFMUstate(c, &state), fmi2OK);
        CHECK(fmi2SerializedFMUstateSize(c, state, &size), fmi2OK);
        fmi2Byte *bytes = malloc(size);
        CHECK(fmi2SerializeFMUstate(c, state, bytes, size), fmi2OK);
        CHECK(fmi2DeSerializeFMUstate(c, bytes, size, &copy), fmi2OK);
        free(bytes);
        CHECK(fmi2SetFMUstate(c, copy), fmi2OK);
        CHECK(fmi2FreeFMUstate(c, &copy), fmi2OK);
        CHECK(fmi2FreeFMUstate(c, &state), fmi2OK);
        CHECK(fmi2GetFMUstate(c, &kept), fmi2OK); /* freed by fmi2FreeInstance */
        fmi2FreeInstance(c);

        /* Model Exchange. */
        c = fmi2Instantiate("leak check ME", fmi2ModelExchange, argv[2], "file:///tmp/a%20b", &cb, fmi2False,
                            fmi2False);
        if (!c) {
            fprintf(stderr, "cycle %ld: fmi2Instantiate (Model Exchange) returned NULL\n", k);
            return 1;
        }
        CHECK(fmi2SetContinuousStates(c, NULL, nx), fmi2Error);
        CHECK(fmi2Reset(c), fmi2OK);
        CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
        CHECK(fmi2EnterInitializationMode(c), fmi2OK);
        CHECK(fmi2SetReal(c, &tau_m, 1, &tau), fmi2OK);
        CHECK(fmi2ExitInitializationMode(c), fmi2OK);
        fmi2EventInfo info;
        CHECK(fmi2NewDiscreteStates(c, &info), fmi2OK);
        CHECK(fmi2EnterContinuousTimeMode(c), fmi2OK);
        fmi2Real x[MAX_STATES], dx[MAX_STATES], z[MAX_INDICATORS];
        fmi2Boolean enter = fmi2True, terminate = fmi2True;
        CHECK(fmi2GetContinuousStates(c, x, nx), fmi2OK);
        for (int i = 0; i < 5; i++) {
            CHECK(fmi2GetDerivatives(c, dx, nx), fmi2OK);
            for (size_t j = 0; j < nx; j++) x[j] += 1e-5 * dx[j];
            CHECK(fmi2SetTime(c, (i + 1) * 1e-5), fmi2OK);
            CHECK(fmi2SetContinuousStates(c, x, nx), fmi2OK);
            CHECK(fmi2GetEventIndicators(c, z, nz), fmi2OK);
            CHECK(fmi2CompletedIntegratorStep(c, fmi2True, &enter, &terminate), fmi2OK);
        }
        CHECK(fmi2GetReal(c, &omega_m, 1, &w), fmi2OK);
        if (!(w > 0.0) || enter || terminate) {
            fprintf(stderr, "cycle %ld (Model Exchange): omega_m = %g, enterEventMode %d\n", k, w, enter);
            return 1;
        }
        state = copy = kept = NULL;
        CHECK(fmi2GetFMUstate(c, &state), fmi2OK);
        CHECK(fmi2SerializedFMUstateSize(c, state, &size), fmi2OK);
        bytes = malloc(size);
        CHECK(fmi2SerializeFMUstate(c, state, bytes, size), fmi2OK);
        CHECK(fmi2DeSerializeFMUstate(c, bytes, size, &copy), fmi2OK);
        free(bytes);
        CHECK(fmi2SetFMUstate(c, copy), fmi2OK);
        CHECK(fmi2FreeFMUstate(c, &copy), fmi2OK);
        CHECK(fmi2FreeFMUstate(c, &state), fmi2OK);
        CHECK(fmi2EnterEventMode(c), fmi2OK);
        CHECK(fmi2GetFMUstate(c, &kept), fmi2OK); /* freed by fmi2FreeInstance */
        fmi2FreeInstance(c);
    }
    size_t heap_at_end = mallinfo2().uordblks;
    /* No dlclose: the library's static tables (live instances, FMU states, plant cache) must stay
     * mapped, so that valgrind sees them as reachable rather than lost at exit. */
    if (logged < 2 * cycles) {
        fprintf(stderr, "only %d messages logged for %ld refused calls\n", logged, 2 * cycles);
        return 1;
    }
    /* Under valgrind mallinfo2 reports 0; the leak check there is valgrind's. */
    if (heap_at_end > heap_after_warmup + GROWTH_LIMIT) {
        fprintf(stderr, "heap grew from %zu to %zu bytes between cycle %ld and %ld\n", heap_after_warmup,
                heap_at_end, cycles / 10, cycles);
        return 1;
    }
    printf("%ld cycles; heap in use after warm-up %zu bytes, at the end %zu bytes\n", cycles, heap_after_warmup,
           heap_at_end);
    return 0;
}
