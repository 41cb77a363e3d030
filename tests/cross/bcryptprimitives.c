/* Test-only stand-in for Windows' bcryptprimitives.dll, placed beside the cross test's host
 * executable and never in an FMU. Rust's standard library for Windows 10+ imports ProcessPrng from
 * that system DLL (stock on Windows 10 and later), which Wine 8 does not provide; Windows' own
 * search order finds this copy in the executable's directory first.
 *
 * ProcessPrng fills the buffer from the system RNG (BCryptGenRandom, which Wine implements) and,
 * like the original, always reports success. */
#include <windows.h>
#include <bcrypt.h>
#include <stdlib.h>

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T size) {
    while (size > 0) {
        ULONG chunk = size > 0x7fffffff ? 0x7fffffff : (ULONG)size;
        if (!BCRYPT_SUCCESS(BCryptGenRandom(NULL, data, chunk, BCRYPT_USE_SYSTEM_PREFERRED_RNG))) {
            /* The original never fails; a broken RNG must not pass for random bytes. */
            abort();
        }
        data += chunk;
        size -= chunk;
    }
    return TRUE;
}
