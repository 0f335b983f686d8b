//! Report lines over semihosting without `core::fmt` (which would bring panic paths and
//! several kB of code): a fixed line buffer, decimal and hex numbers, SYS_WRITE0.

use orbfix::fix::{protocol, FixError, FixReport};

const CAP: usize = 160;

/// One report line, sent with a trailing newline; text beyond the capacity is dropped.
pub struct Line {
    buf: [u8; CAP],
    len: usize,
}

impl Line {
    /// An empty line.
    pub fn new() -> Self {
        Self {
            buf: [0; CAP],
            len: 0,
        }
    }

    fn byte(mut self, b: u8) -> Self {
        // Keep two bytes for "\n\0".
        if self.len + 2 < CAP {
            if let Some(slot) = self.buf.get_mut(self.len) {
                *slot = b;
                self.len += 1;
            }
        }
        self
    }

    /// Appends text.
    pub fn str(mut self, s: &str) -> Self {
        for &b in s.as_bytes() {
            self = self.byte(b);
        }
        self
    }

    /// Appends an unsigned decimal number.
    pub fn u64(mut self, mut v: u64) -> Self {
        let mut digits = [0u8; 20];
        let mut n = 0;
        loop {
            if let Some(d) = digits.get_mut(n) {
                *d = b'0' + (v % 10) as u8;
            }
            n += 1;
            v /= 10;
            if v == 0 || n >= digits.len() {
                break;
            }
        }
        while n > 0 {
            n -= 1;
            self = self.byte(digits.get(n).copied().unwrap_or(b'?'));
        }
        self
    }

    /// Appends a signed decimal number.
    pub fn i32(self, v: i32) -> Self {
        if v < 0 {
            self.str("-").u64(v.unsigned_abs() as u64)
        } else {
            self.u64(v as u64)
        }
    }

    /// Appends `0x` and eight hex digits.
    pub fn hex32(mut self, v: u32) -> Self {
        self = self.str("0x");
        for i in (0..8).rev() {
            let d = ((v >> (4 * i)) & 0xF) as u8;
            self = self.byte(if d < 10 { b'0' + d } else { b'a' + d - 10 });
        }
        self
    }

    /// Writes the line and a newline to the host's console.
    pub fn send(self) {
        let mut buf = self.buf;
        if let Some(nl) = buf.get_mut(self.len) {
            *nl = b'\n';
        }
        if let Some(nul) = buf.get_mut(self.len + 1) {
            *nul = 0;
        }
        // Safety: SYS_WRITE0 reads a NUL-terminated string; `buf` always ends in one (the
        // last two bytes are reserved) and lives until the call returns.
        unsafe {
            cortex_m_semihosting::syscall1(cortex_m_semihosting::nr::WRITE0, buf.as_ptr() as usize);
        }
    }
}

/// The `RESULT` lines of a fix, in the order and with the values of the core's protocol
/// ([`orbfix::fix::protocol`]).
pub fn results(r: &FixReport, digest: u32) {
    for (k, v) in protocol::RESULT_KEYS
        .iter()
        .zip(protocol::result_values(r, digest))
    {
        Line::new()
            .str(protocol::RESULT)
            .str(" ")
            .str(k)
            .str(" ")
            .hex32(v)
            .send();
    }
}

/// `<tag> <key> 0x<hex>` lines, one per key and value (the protocol's `FUSION-RESULT` and
/// `HEADING-RESULT` records).
pub fn keyed(tag: &str, keys: &[&str], values: &[u32]) {
    for (k, v) in keys.iter().zip(values) {
        Line::new()
            .str(tag)
            .str(" ")
            .str(k)
            .str(" ")
            .hex32(*v)
            .send();
    }
}

/// A short text for a fix error (no `core::fmt` on the target).
pub fn fix_error(e: &FixError) -> &'static str {
    match e {
        FixError::BadConfig { field } => field,
        FixError::MapProduct(_) => "map product refused",
        FixError::MapMismatch { what } => what,
        FixError::Weights(_) => "weight file refused",
        FixError::PriorOutsideMap => "prior outside the map",
        FixError::Reproject(_) => "reprojection failed",
        FixError::Range(_) => "range reprojection failed",
        FixError::Stereo(_) => "stereo settings refused",
        FixError::Match(_) => "matching failed",
        FixError::Nn(_) => "network failed",
        FixError::ScratchTooSmall { buffer } => buffer,
    }
}

/// Ends the program through semihosting: QEMU exits with 0 if `ok`, else 1.
pub fn exit(ok: bool) -> ! {
    cortex_m_semihosting::debug::exit(if ok {
        cortex_m_semihosting::debug::EXIT_SUCCESS
    } else {
        cortex_m_semihosting::debug::EXIT_FAILURE
    });
    #[allow(clippy::empty_loop)]
    loop {}
}
