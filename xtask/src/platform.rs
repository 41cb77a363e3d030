//! The platforms the FMU's library is built for: where each binary goes in an archive, which
//! tools build, inspect and run it on this (x86_64 Linux) machine, and which Debian package
//! brings each tool.

use std::path::PathBuf;

/// A program this machine needs for a platform, and the Debian package that provides it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tool {
    pub command: &'static str,
    pub package: &'static str,
}

/// How the library's exports and imports are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinaryFormat {
    /// ELF shared object: `nm -D`.
    Elf,
    /// Windows DLL: `objdump -p` (export and import tables).
    Pe,
}

/// How a program built for the platform runs here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Runner {
    Native,
    /// Windows programs: `wine program.exe ...`.
    Wine(Tool),
    /// Linux programs of another architecture: `qemu-<arch> -L <sysroot> program ...`.
    QemuUser {
        qemu: Tool,
        sysroot: &'static str,
    },
}

#[derive(Debug, PartialEq, Eq)]
pub struct Platform {
    /// Name in messages and in the test's directories.
    pub name: &'static str,
    pub rust_target: &'static str,
    /// Folder under `binaries/` of an FMI 2.0 archive (FMI 2.0 §2.3 defines win32, win64,
    /// linux32, linux64, darwin32, darwin64): None where FMI 2.0 has no folder for it.
    pub fmi2_folder: Option<&'static str>,
    /// Platform tuple folder under `binaries/` of an FMI 3.0 archive (FMI 3.0 §2.5.1.4).
    pub fmi3_folder: &'static str,
    /// The file cargo writes for the `backlash_fmu` cdylib.
    pub library_file: &'static str,
    /// Extension of the library in an archive, `<modelIdentifier>.<extension>`.
    pub extension: &'static str,
    pub format: BinaryFormat,
    /// C compiler for the platform: builds the test host and links the Rust cdylib.
    pub c_compiler: Tool,
    /// Prefix of the binutils (`nm`, `objdump`) that read this platform's binaries.
    pub binutils_prefix: &'static str,
    pub runner: Runner,
}

/// The machine's own platform: built by plain `cargo build`, packed by every `cargo xtask fmu`.
pub const LINUX64: Platform = Platform {
    name: "linux64",
    rust_target: "x86_64-unknown-linux-gnu",
    fmi2_folder: Some("linux64"),
    fmi3_folder: "x86_64-linux",
    library_file: "libbacklash_fmu.so",
    extension: "so",
    format: BinaryFormat::Elf,
    c_compiler: Tool {
        command: "cc",
        package: "gcc",
    },
    binutils_prefix: "",
    runner: Runner::Native,
};

/// 64-bit Windows through MinGW-w64: the DLL imports only system DLLs (msvcrt, kernel32, ...).
pub const WIN64: Platform = Platform {
    name: "win64",
    rust_target: "x86_64-pc-windows-gnu",
    fmi2_folder: Some("win64"),
    fmi3_folder: "x86_64-windows",
    library_file: "backlash_fmu.dll",
    extension: "dll",
    format: BinaryFormat::Pe,
    c_compiler: Tool {
        command: "x86_64-w64-mingw32-gcc",
        package: "gcc-mingw-w64-x86-64",
    },
    binutils_prefix: "x86_64-w64-mingw32-",
    runner: Runner::Wine(Tool {
        command: "wine",
        package: "wine wine64",
    }),
};

/// 64-bit ARM Linux (glibc): FMI 2.0 has no folder for it; FMI 3.0 archives carry it.
pub const AARCH64_LINUX: Platform = Platform {
    name: "aarch64-linux",
    rust_target: "aarch64-unknown-linux-gnu",
    fmi2_folder: None,
    fmi3_folder: "aarch64-linux",
    library_file: "libbacklash_fmu.so",
    extension: "so",
    format: BinaryFormat::Elf,
    c_compiler: Tool {
        command: "aarch64-linux-gnu-gcc",
        package: "gcc-aarch64-linux-gnu",
    },
    binutils_prefix: "aarch64-linux-gnu-",
    runner: Runner::QemuUser {
        qemu: Tool {
            command: "qemu-aarch64",
            package: "qemu-user",
        },
        sysroot: "/usr/aarch64-linux-gnu",
    },
};

/// Every platform, the host first.
pub const ALL: [&Platform; 3] = [&LINUX64, &WIN64, &AARCH64_LINUX];

/// The platforms built from another machine's standard library.
pub fn cross() -> impl Iterator<Item = &'static Platform> {
    ALL.into_iter().filter(|p| !p.is_host())
}

impl Platform {
    pub fn is_host(&self) -> bool {
        *self == LINUX64
    }

    /// The tools this machine needs to build, inspect and run the platform's binaries (the
    /// Rust standard library aside: see `cross::toolchain`).
    pub fn tools(&self) -> Vec<Tool> {
        let mut tools = vec![self.c_compiler];
        match self.runner {
            Runner::Native => {}
            Runner::Wine(wine) => tools.push(wine),
            Runner::QemuUser { qemu, .. } => tools.push(qemu),
        }
        tools
    }

    pub fn binutil(&self, name: &str) -> String {
        format!("{}{name}", self.binutils_prefix)
    }

    /// Name of the library inside an archive.
    pub fn archive_file(&self, model_identifier: &str) -> String {
        format!("{model_identifier}.{}", self.extension)
    }
}

/// A library built for a platform.
#[derive(Clone, Debug)]
pub struct Built {
    pub platform: &'static Platform,
    pub path: PathBuf,
}
