//! The machine a run measures on: the CPU's model string, its vendor family and model
//! numbers, the SIMD level run-time dispatch can choose, and the number of logical CPUs.
//!
//! Every `rttest` command prints [`Machine::detect`]'s one-line `Display` above its text
//! results and adds `cpu` and `simd` to its JSON objects, so a figure always carries the
//! machine that made it (the docs quote that line and never name a CPU by hand).
//!
//! The CPU is read once per process: on Linux from the first processor's `model name`,
//! `cpu family` and `model` lines of `/proc/cpuinfo`; elsewhere, or when that file is
//! missing or has no model name, from the x86 CPUID brand string (leaves
//! `0x8000_0002..=0x8000_0004`) and leaf 1's display family and model; else `unknown`.
//! Nothing here panics on an odd file.

use std::fmt;
use std::sync::OnceLock;

pub use kdtree::isa::SimdLevel;

/// The CPU as its vendor names it: the model string and, where known, the family and model
/// numbers (AMD's EPYC 9004, Zen 4, is family 25 model 17; its EPYC 7001, Zen 1, family 23
/// model 1).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cpu {
    /// The model string (`AMD EPYC 9R14 96-Core Processor`), `unknown` if none was found.
    pub name: String,
    /// The vendor's (display) family number, if known.
    pub family: Option<u32>,
    /// The vendor's (display) model number, if known.
    pub model: Option<u32>,
}

impl Cpu {
    /// The CPU of the first processor block of a `/proc/cpuinfo` text: its `model name`,
    /// `cpu family` and `model` lines. `None` without a non-empty `model name`; a family or
    /// model that is not a decimal number is left out.
    pub fn from_cpuinfo(text: &str) -> Option<Cpu> {
        let mut cpu = Cpu { name: String::new(), family: None, model: None };
        let mut in_block = false;
        for line in text.lines() {
            let Some((key, value)) = line.split_once(':') else {
                // A blank line ends the first processor's block.
                if line.trim().is_empty() && in_block {
                    break;
                }
                continue;
            };
            in_block = true;
            let value = value.trim();
            match key.trim() {
                "model name" if cpu.name.is_empty() => cpu.name = squeeze(value),
                "cpu family" if cpu.family.is_none() => cpu.family = value.parse().ok(),
                "model" if cpu.model.is_none() => cpu.model = value.parse().ok(),
                _ => {}
            }
        }
        (!cpu.name.is_empty()).then_some(cpu)
    }

    /// The CPU from the x86 CPUID instruction: the brand string of leaves
    /// `0x8000_0002..=0x8000_0004` and the display family and model of leaf 1. `None` on
    /// other architectures or without a brand string.
    pub fn from_cpuid() -> Option<Cpu> {
        #[cfg(target_arch = "x86_64")]
        {
            let leaf = |n: u32| {
                // `__cpuid` is unsafe before Rust 1.89 and safe since.
                // SAFETY: every x86-64 CPU has the CPUID instruction.
                #[allow(unused_unsafe)]
                let r = unsafe { core::arch::x86_64::__cpuid(n) };
                [r.eax, r.ebx, r.ecx, r.edx]
            };
            if leaf(0x8000_0000)[0] < 0x8000_0004 {
                return None;
            }
            let bytes: Vec<u8> =
                (0x8000_0002..=0x8000_0004).flat_map(leaf).flat_map(u32::to_le_bytes).take_while(|&b| b != 0).collect();
            let name = squeeze(&String::from_utf8_lossy(&bytes));
            if name.is_empty() {
                return None;
            }
            let (family, model) = display_family_model(leaf(1)[0]);
            Some(Cpu { name, family: Some(family), model: Some(model) })
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            None
        }
    }

    /// This CPU: `/proc/cpuinfo` on Linux, else CPUID, else `unknown`.
    pub fn detect() -> Cpu {
        let from_file = || std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|t| Cpu::from_cpuinfo(&t));
        let from_file = if cfg!(target_os = "linux") { from_file() } else { None };
        from_file.or_else(Cpu::from_cpuid).unwrap_or_else(|| Cpu { name: "unknown".into(), family: None, model: None })
    }
}

impl fmt::Display for Cpu {
    /// `NAME (family F model M)`, or the name alone when either number is unknown.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name)?;
        if let (Some(family), Some(model)) = (self.family, self.model) {
            write!(f, " (family {family} model {model})")?;
        }
        Ok(())
    }
}

/// CPUID leaf 1's EAX as (display family, display model), as Intel's and AMD's manuals
/// define them: the extended family is added when the base family is 15, and the extended
/// model is prepended when the base family is 6 or 15. Only x86-64 reads CPUID; the decoding
/// is tested on every target.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn display_family_model(eax: u32) -> (u32, u32) {
    let base_family = (eax >> 8) & 0xf;
    let base_model = (eax >> 4) & 0xf;
    let family = if base_family == 15 { base_family + ((eax >> 20) & 0xff) } else { base_family };
    let model = if base_family == 6 || base_family == 15 { ((eax >> 16) & 0xf) << 4 | base_model } else { base_model };
    (family, model)
}

/// `s` with runs of whitespace made one space and the ends trimmed (brand strings are
/// padded).
fn squeeze(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The machine a run measures on.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Machine {
    /// The CPU.
    pub cpu: Cpu,
    /// The SIMD level the kernels bind to: the widest the CPU has, capped by `--simd`
    /// ([`SimdLevel::active`]).
    pub simd: SimdLevel,
    /// Logical CPUs (hardware threads) this process may run on
    /// (`std::thread::available_parallelism`, 1 if unknown).
    pub threads: usize,
}

impl Machine {
    /// This machine: its CPU and threads detected on the first call and cached for the
    /// process, its SIMD level the active one now ([`SimdLevel::active`]).
    pub fn detect() -> Machine {
        static MACHINE: OnceLock<(Cpu, usize)> = OnceLock::new();
        let (cpu, threads) =
            MACHINE.get_or_init(|| (Cpu::detect(), std::thread::available_parallelism().map_or(1, |n| n.get())));
        Machine { cpu: cpu.clone(), simd: SimdLevel::active(), threads: *threads }
    }
}

impl fmt::Display for Machine {
    /// One line: `cpu: NAME (family F model M), simd: LEVEL, N threads`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = if self.threads == 1 { "" } else { "s" };
        write!(f, "cpu: {}, simd: {}, {} thread{s}", self.cpu, self.simd, self.threads)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The start of a Zen 4 machine's `/proc/cpuinfo` (two processors, the second a
    /// different model to check that only the first block counts).
    const ZEN4: &str = "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 17\n\
        model name\t: AMD EPYC 9R14 96-Core Processor\nstepping\t: 1\n\
        flags\t\t: fpu vme de pse avx2 avx512f avx512vl\n\n\
        processor\t: 1\nvendor_id\t: AuthenticAMD\ncpu family\t: 23\nmodel\t\t: 1\n\
        model name\t: AMD EPYC 7571\n";

    #[test]
    fn the_line_names_the_first_processor_of_a_cpuinfo_text() {
        let cpu = Cpu::from_cpuinfo(ZEN4).expect("a model name");
        assert_eq!(cpu, Cpu { name: "AMD EPYC 9R14 96-Core Processor".into(), family: Some(25), model: Some(17) });
        let machine = Machine { cpu, simd: SimdLevel::Avx512, threads: 2 };
        assert_eq!(
            machine.to_string(),
            "cpu: AMD EPYC 9R14 96-Core Processor (family 25 model 17), simd: avx512, 2 threads"
        );
        let one = Machine { threads: 1, simd: SimdLevel::Scalar, ..machine };
        assert!(one.to_string().ends_with("simd: scalar, 1 thread"), "{one}");
    }

    #[test]
    fn odd_cpuinfo_texts_fall_back_without_panicking() {
        for text in ["", "\n\n", "processor : 0\n", "model name :   \n", "garbage\u{0}\u{ff}:::\n", ":\n:"] {
            assert_eq!(Cpu::from_cpuinfo(text), None, "{text:?}");
        }
        // ARM's cpuinfo: no model name line in the first block.
        assert_eq!(Cpu::from_cpuinfo("processor\t: 0\nBogoMIPS\t: 50.00\nCPU part\t: 0xd0c\n"), None);
        // Numbers that are not numbers are left out, and the line shows the name alone.
        let cpu = Cpu::from_cpuinfo("cpu family : x\nmodel : 0x11\nmodel name :  Some   CPU \n").expect("a name");
        assert_eq!(cpu, Cpu { name: "Some CPU".into(), family: None, model: None });
        assert_eq!(cpu.to_string(), "Some CPU");
    }

    #[test]
    fn the_detected_machine_is_cached_and_named() {
        let machine = Machine::detect();
        assert_eq!(machine, Machine::detect(), "detected once");
        assert!(!machine.cpu.name.is_empty() && machine.threads >= 1);
        let line = machine.to_string();
        assert!(line.starts_with("cpu: ") && line.contains(&format!("simd: {}, ", machine.simd.name())), "{line}");
    }

    #[test]
    fn cpuid_family_and_model_follow_the_manuals() {
        // Zen 4 (EPYC 9004): family 0xF + 0xA = 25, model 0x11 = 17.
        assert_eq!(display_family_model(0x00A1_0F11), (25, 17));
        // Zen 1 (EPYC 7001): family 0xF + 0x8 = 23, model 1.
        assert_eq!(display_family_model(0x0080_0F12), (23, 1));
        // Intel Sapphire Rapids: family 6, model 0x8F = 143.
        assert_eq!(display_family_model(0x0008_06F8), (6, 143));
        #[cfg(target_arch = "x86_64")]
        if let Some(cpu) = Cpu::from_cpuid() {
            assert!(!cpu.name.is_empty() && cpu.name.trim() == cpu.name, "{cpu}");
        }
    }
}
