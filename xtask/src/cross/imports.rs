//! The Windows DLL may import only DLLs that every Windows 10 or later installation has: an
//! import of a MinGW runtime DLL (libgcc_s_seh-1, libwinpthread-1, libstdc++-6) or of a Visual
//! C++ redistributable (vcruntime140) would make the FMU fail to load on a stock machine.

use std::path::Path;
use std::process::Command;

use crate::platform::Platform;
use crate::util;

/// System DLLs of every Windows 10+ installation (System32), lower case. msvcrt.dll is the C
/// runtime MinGW-w64 links against by default; it has shipped with Windows since Windows 2000.
/// bcryptprimitives.dll (ProcessPrng, Rust's random numbers) is there since Windows 8.
const STOCK_DLLS: [&str; 9] = [
    "kernel32.dll",
    "ntdll.dll",
    "msvcrt.dll",
    "ucrtbase.dll",
    "advapi32.dll",
    "bcrypt.dll",
    "bcryptprimitives.dll",
    "userenv.dll",
    "ws2_32.dll",
];

/// API sets (api-ms-win-core-synch-l1-2-0.dll, api-ms-win-crt-*.dll): names that the Windows 10
/// loader resolves to system DLLs.
const API_SET_PREFIX: &str = "api-ms-win-";

/// The DLLs `dll` imports, read with the platform's `objdump -p`.
pub fn imported_dlls(platform: &Platform, dll: &Path) -> Result<Vec<String>, String> {
    let listing = util::output(Command::new(platform.binutil("objdump")).arg("-p").arg(dll))?;
    Ok(parse_imports(&listing))
}

fn parse_imports(objdump: &str) -> Vec<String> {
    objdump
        .lines()
        .filter_map(|line| line.trim().strip_prefix("DLL Name:"))
        .map(|name| name.trim().to_string())
        .collect()
}

fn is_stock(dll: &str) -> bool {
    let dll = dll.to_ascii_lowercase();
    STOCK_DLLS.contains(&dll.as_str()) || (dll.starts_with(API_SET_PREFIX) && dll.ends_with(".dll"))
}

/// Checks the import table of `dll`; returns the imported DLLs (all of them stock).
pub fn check(platform: &Platform, dll: &Path) -> Result<Vec<String>, String> {
    let imports = imported_dlls(platform, dll)?;
    verdict(&imports).map_err(|e| format!("{}: {e}", util::shown(dll)))?;
    Ok(imports)
}

fn verdict(imports: &[String]) -> Result<(), String> {
    if imports.is_empty() {
        // Every DLL imports at least kernel32: an empty list means objdump's format changed.
        return Err("objdump -p lists no imported DLL".into());
    }
    let foreign: Vec<&str> = imports.iter().map(String::as_str).filter(|d| !is_stock(d)).collect();
    if foreign.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "imports DLLs that a stock Windows 10 does not have: {} (all imports: {})",
            foreign.join(", "),
            imports.join(", ")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LISTING: &str = "\
There is an import table in .idata at 0x6b128000

The Import Tables (interpreted .idata section contents)
 vma:            Hint    Time      Forward  DLL       First
\tDLL Name: KERNEL32.dll
\tvma:  Hint/Ord Member-Name Bound-To
\t128258\t  123  CloseHandle

\tDLL Name: api-ms-win-core-synch-l1-2-0.dll
\tDLL Name: bcryptprimitives.dll
";

    #[test]
    fn the_import_table_is_read_from_objdump() {
        assert_eq!(
            parse_imports(LISTING),
            [
                "KERNEL32.dll",
                "api-ms-win-core-synch-l1-2-0.dll",
                "bcryptprimitives.dll"
            ]
        );
        assert!(verdict(&parse_imports(LISTING)).is_ok());
    }

    #[test]
    fn runtime_dlls_that_windows_lacks_are_refused() {
        for foreign in [
            "libgcc_s_seh-1.dll",
            "libwinpthread-1.dll",
            "libstdc++-6.dll",
            "VCRUNTIME140.dll",
        ] {
            let imports = vec!["KERNEL32.dll".to_string(), foreign.to_string()];
            let error = verdict(&imports).unwrap_err();
            assert!(error.contains(foreign), "{error}");
        }
        assert!(verdict(&[]).is_err());
        assert!(!is_stock("api-ms-win-core-synch-l1-2-0.so"));
    }
}
