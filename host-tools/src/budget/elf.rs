//! Memory sizes and panic call sites read from the firmware ELF.

use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::collections::BTreeMap;

/// Address ranges of mps2-an500 as used by memory.x.
const FLASH: (u64, u64) = (0x0000_0000, 0x0040_0000);
const SRAM: (u64, u64) = (0x2000_0000, 0x2040_0000);
const PSRAM: (u64, u64) = (0x6000_0000, 0x6100_0000);

/// Memory sizes read from the firmware ELF.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ElfSizes {
    /// Bytes stored in flash: code, read-only data, the initial values of `.data`.
    pub flash_bytes: u64,
    /// Static working memory in SRAM: `.data`, `.bss`, `.uninit`.
    pub static_ram_bytes: u64,
    /// Inputs in external memory (`.psram`: frames and map), not working memory.
    pub external_input_bytes: u64,
    /// Working tables in external memory (`.xscratch`: the reprojection table).
    pub external_scratch_bytes: u64,
    /// Size of the stack region (memory.x STACK), bytes.
    pub stack_region_bytes: u64,
}

/// Reads flash, static RAM and external-memory sizes from an ELF (by load segments and
/// allocated sections, classified by the mps2-an500 address map).
pub fn elf_sizes(data: &[u8]) -> Result<ElfSizes> {
    use object::read::elf::{ElfFile32, ProgramHeader};
    use object::{Endianness, Object, ObjectSection, ObjectSymbol, SectionFlags};
    let file = ElfFile32::<Endianness>::parse(data)
        .context("the firmware file is not a valid 32-bit ELF")?;
    let e = file.endian();
    let inside = |a: u64, r: (u64, u64)| a >= r.0 && a < r.1;
    let mut s = ElfSizes::default();
    for ph in file.elf_program_headers() {
        // The load (physical) address decides where the bytes are stored.
        if ph.p_type(e) == object::elf::PT_LOAD && inside(ph.p_paddr(e) as u64, FLASH) {
            s.flash_bytes += ph.p_filesz(e) as u64;
        }
    }
    for sec in file.sections() {
        let alloc = match sec.flags() {
            SectionFlags::Elf { sh_flags } => sh_flags & u64::from(object::elf::SHF_ALLOC) != 0,
            _ => false,
        };
        if !alloc || sec.size() == 0 {
            continue;
        }
        if inside(sec.address(), SRAM) {
            s.static_ram_bytes += sec.size();
        } else if inside(sec.address(), PSRAM) {
            if sec.name().is_ok_and(|n| n.starts_with(".xscratch")) {
                s.external_scratch_bytes += sec.size();
            } else {
                s.external_input_bytes += sec.size();
            }
        }
    }
    let sym = |name: &str| {
        file.symbols()
            .find(|x| x.name() == Ok(name))
            .map(|x| x.address())
    };
    if let (Some(top), Some(bottom)) = (sym("_stack_start"), sym("_stack_end")) {
        s.stack_region_bytes = top.saturating_sub(bottom);
    }
    if s.flash_bytes == 0 {
        bail!("the ELF has nothing to load into flash (0x0..0x400000): is it the orbfix firmware for mps2-an500?");
    }
    Ok(s)
}

/// Whether a symbol name is one of core's panic entry points (or the panic handler).
fn is_panic_symbol(name: &str) -> bool {
    // `_fail` covers core's `*_fail` / `*_failed` helpers (slice index, copy length,
    // unwrap, expect) that lead to the panic handler.
    ["panic", "_fail"].iter().any(|k| name.contains(k))
}

/// Target of a 32-bit Thumb-2 `BL` (T1) or `B.W` (T4) at `addr` made of halfwords `h1`,
/// `h2`, or `None` if they are not one.
pub fn thumb_branch_target(addr: u64, h1: u16, h2: u16) -> Option<u64> {
    let (h1, h2) = (h1 as u32, h2 as u32);
    // BL: 11110 S imm10 | 11 J1 1 J2 imm11; B.W: 11110 S imm10 | 10 J1 1 J2 imm11.
    if h1 >> 11 != 0b11110 || h2 >> 15 != 1 || (h2 >> 12) & 1 != 1 {
        return None;
    }
    let s = (h1 >> 10) & 1;
    let (j1, j2) = ((h2 >> 13) & 1, (h2 >> 11) & 1);
    let (i1, i2) = (!(j1 ^ s) & 1, !(j2 ^ s) & 1);
    let imm = (s << 24) | (i1 << 23) | (i2 << 22) | ((h1 & 0x3FF) << 12) | ((h2 & 0x7FF) << 1);
    let off = ((imm << 7) as i32) >> 7; // sign-extend 25 bits
    Some((addr as i64 + 4 + off as i64) as u64)
}

/// Call sites of panic entry points in a Thumb-2 ELF: `(caller, callee, calls)`, demangled,
/// callers that are themselves panic functions left out. Found by decoding every 32-bit
/// `BL` / `B.W` in executable sections and matching its target against panic symbols, so
/// it works on the linked firmware without a disassembler.
pub fn panic_sites(data: &[u8]) -> Result<Vec<(String, String, usize)>> {
    use object::{Object, ObjectSection, ObjectSymbol, SectionKind, SymbolKind};
    let file = object::File::parse(data).context("the firmware file is not a valid ELF")?;
    // Function symbols: (start, end, demangled name); Thumb addresses have bit 0 set.
    let mut funcs: Vec<(u64, u64, String)> = file
        .symbols()
        .filter(|s| s.kind() == SymbolKind::Text)
        .filter_map(|s| {
            let name = s.name().ok()?;
            let start = s.address() & !1;
            Some((
                start,
                start + s.size().max(2),
                format!("{:#}", rustc_demangle::demangle(name)),
            ))
        })
        .collect();
    funcs.sort();
    let panics: std::collections::HashSet<u64> = funcs
        .iter()
        .filter(|f| is_panic_symbol(&f.2))
        .map(|f| f.0)
        .collect();
    let name_at = |addr: u64| -> Option<&(u64, u64, String)> {
        let i = funcs.partition_point(|f| f.0 <= addr);
        funcs.get(i.checked_sub(1)?).filter(|f| addr < f.1)
    };
    let mut sites: BTreeMap<(String, String), usize> = BTreeMap::new();
    for sec in file.sections().filter(|s| s.kind() == SectionKind::Text) {
        let bytes = sec
            .data()
            .context("cannot read a code section of the firmware")?;
        let base = sec.address();
        let hw = |i: usize| -> Option<u32> {
            Some(u16::from_le_bytes([*bytes.get(i)?, *bytes.get(i + 1)?]) as u32)
        };
        let mut i = 0;
        while i + 4 <= bytes.len() {
            let (Some(h1), Some(h2)) = (hw(i), hw(i + 2)) else {
                break;
            };
            if let Some(target) = thumb_branch_target(base + i as u64, h1 as u16, h2 as u16) {
                if panics.contains(&target) {
                    let caller = name_at(base + i as u64)
                        .map(|f| f.2.clone())
                        .unwrap_or_else(|| "?".into());
                    if !is_panic_symbol(&caller) {
                        let callee = name_at(target)
                            .map(|f| f.2.clone())
                            .unwrap_or_else(|| "?".into());
                        *sites.entry((caller, callee)).or_default() += 1;
                    }
                }
            }
            i += 2;
        }
    }
    Ok(sites.into_iter().map(|((a, b), n)| (a, b, n)).collect())
}
