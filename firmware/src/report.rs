//! Report lines over semihosting without `core::fmt` (which would bring panic paths and
//! several kB of code): a fixed line buffer, decimal and hex numbers, SYS_WRITE0.

use orbfix::flight_run::{status_code, FlightError, FlightOutputs};

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

/// The `RESULT` lines of a fix (format shared with `orbfix_host::budget::host_results`;
/// `f32` as exact bit patterns).
pub fn outputs(out: &FlightOutputs) {
    let l = &out.lut;
    let a = &out.apply;
    let f = &out.fix;
    let mut line = Line::new().str("RESULT lut");
    for v in [
        l.valid_cells,
        l.blended_cells,
        l.dropped_taps,
        l.cells_per_view[0],
        l.cells_per_view[1],
        l.cells_per_view[2],
        l.cells_per_view[3],
    ] {
        line = line.str(" ").u64(v as u64);
    }
    line.send();
    let mut line = Line::new().str("RESULT apply");
    for s in a.status {
        line = line.str(" ").u64(status_code(s) as u64);
    }
    line.str(" ")
        .u64(a.valid_cells as u64)
        .str(" ")
        .u64(a.lost_cells as u64)
        .send();
    Line::new()
        .str("RESULT top_hash ")
        .hex32(out.top_hash)
        .send();
    Line::new()
        .str("RESULT mask_hash ")
        .hex32(out.mask_hash)
        .send();
    Line::new()
        .str("RESULT response ")
        .hex32(out.response_hash)
        .str(" ")
        .u64(out.response_len as u64)
        .send();
    Line::new()
        .str("RESULT candidates ")
        .hex32(out.candidates_hash)
        .str(" ")
        .u64(f.candidates as u64)
        .send();
    let mut line = Line::new().str("RESULT fix");
    for v in [
        f.x_m,
        f.y_m,
        f.score,
        f.confidence,
        f.peak_score,
        f.second_score,
    ] {
        line = line.str(" ").hex32(v.to_bits());
    }
    line.str(" ").u64(f.on_border as u64).send();
    Line::new()
        .str("RESULT ops ")
        .u64(out.ops.macs)
        .str(" ")
        .u64(out.ops.windows)
        .str(" ")
        .u64(out.ops.downsample_px)
        .send();
    Line::new()
        .str("RESULT nn ")
        .hex32(out.embedding_hash)
        .str(" ")
        .hex32(out.nn_scores_hash)
        .str(" ")
        .u64(out.nn_windows as u64)
        .str(" ")
        .u64(out.nn_best.0 as u64)
        .str(" ")
        .i32(out.nn_best.1)
        .send();
    Line::new().str("RESULT digest ").hex32(out.digest()).send();
}

/// A short text for a flight error.
#[cfg_attr(feature = "no-fix", allow(dead_code))]
pub fn flight_error(e: &FlightError) -> &'static str {
    match e {
        FlightError::Reproject(_) => "reprojection failed (camera, grid, frame or buffer sizes)",
        FlightError::Localize(_) => "localization failed (coverage, resolution, prior or buffers)",
        FlightError::Nn(_) => "CNN failed (too little valid top-down image or flat input)",
        FlightError::Weights => "shipped CNN weights did not validate",
        FlightError::BadMapEmbeddings => "map-window embeddings missing or malformed",
        FlightError::ScratchTooSmall => "scratch buffers too small",
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
