//! Report lines over semihosting without `core::fmt` (which would bring panic paths and
//! several kB of code): a fixed line buffer, decimal and hex numbers, SYS_WRITE0.

use orbfix::flight_run::{FlightError, ImageStats};

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

/// `RESULT stats<i> <min> <max> <sum> <hash>` (i = 0..4 frames, 4 = map).
pub fn stats(i: u8, s: &ImageStats) {
    Line::new()
        .str("RESULT stats")
        .u64(i as u64)
        .str(" ")
        .u64(s.min as u64)
        .str(" ")
        .u64(s.max as u64)
        .str(" ")
        .u64(s.sum)
        .str(" ")
        .hex32(s.hash)
        .send();
}

/// A short text for a flight error.
pub fn flight_error(e: &FlightError) -> &'static str {
    match e {
        FlightError::Camera(_) => "camera or pose out of range",
        FlightError::FrameSize { .. } => "frame size does not match the rig",
        FlightError::BlackFrame { .. } => "black frame",
        FlightError::SaturatedFrame { .. } => "saturated frame",
        FlightError::FlatMap => "flat map",
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
