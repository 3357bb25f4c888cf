/* A host for the FMU that is no Python (as OMSimulator, Simulink and fmi_adapter are):
 * it loads the binary of an extracted FMU, lifts for 1 s at 10 ms steps, prints q1, tries a
 * step the FMU must refuse, and exits. The FMU needs nothing from its environment: no
 * Python, no variable set.
 *
 *   fmu_c_host EXTRACTED_FMU_FOLDER   ->  "q1 <metres after 1 s>" and "refused <status>"
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list args;
    va_start(args, message);
    printf("log %s: ", category);
    vprintf(message, args);
    printf("\n");
    va_end(args);
}

#define LOAD(name)                                       \
    name##TYPE *name = (name##TYPE *)dlsym(lib, #name);  \
    if (!name) {                                         \
        printf("missing %s\n", #name);                   \
        return 2;                                        \
    }

int main(int argc, char **argv) {
    char binary[4096], resources[4096];
    if (argc != 2) return 2;
    snprintf(binary, sizeof binary, "%s/binaries/linux64/boom_drive.so", argv[1]);
    snprintf(resources, sizeof resources, "file://%s/resources", argv[1]);
    void *lib = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        printf("dlopen: %s\n", dlerror());
        return 2;
    }
    LOAD(fmi2Instantiate)
    LOAD(fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode)
    LOAD(fmi2SetReal)
    LOAD(fmi2GetReal)
    LOAD(fmi2DoStep)
    LOAD(fmi2Terminate)
    LOAD(fmi2FreeInstance)
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("boom", fmi2CoSimulation, "", resources, &callbacks, fmi2False, fmi2True);
    if (!c) {
        printf("instantiate failed\n");
        return 1;
    }
    fmi2ValueReference valve = 0, q1 = 3; /* the first input and the first output (after the three inputs) */
    fmi2Real opening = 1.0, value = 0.0;
    if (fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
        fmi2EnterInitializationMode(c) != fmi2OK || fmi2ExitInitializationMode(c) != fmi2OK) {
        printf("initialization failed\n");
        return 1;
    }
    fmi2SetReal(c, &valve, 1, &opening);
    for (int k = 0; k < 100; k++) {
        if (fmi2DoStep(c, k * 0.01, 0.01, fmi2True) != fmi2OK) {
            printf("step %d failed\n", k);
            return 1;
        }
    }
    fmi2GetReal(c, &q1, 1, &value);
    printf("q1 %.17g\n", value);
    printf("refused %d\n", (int)fmi2DoStep(c, 1.0, 0.0015, fmi2True));
    fmi2Terminate(c);
    fmi2FreeInstance(c);
    return 0;
}
