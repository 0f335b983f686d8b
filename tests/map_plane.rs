//! The map product's refinement plane equals the high-pass of any region the fix refines on,
//! wherever the region's boxes are whole (the invariant that lets the plane be made once on
//! the ground instead of around every candidate on board).

use orbfix::image::{ImageView, ImageViewMut};
use orbfix::map_product::{refine_plane_buffer_len, write_refine_plane, RefinePlane};
use orbfix::matcher::prep::{highpass, highpass_buffer_len, rectify};

fn map(w: usize, h: usize, seed: u32) -> Vec<u8> {
    let mut s = seed;
    (0..w * h)
        .map(|i| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            // Texture plus a broad gradient, so the high-pass has something to remove.
            ((s >> 24) as usize / 2 + (i % w) / 3) as u8
        })
        .collect()
}

#[test]
fn plane_equals_the_high_pass_of_every_region_away_from_its_edges() {
    let (w, h) = (150, 120);
    let px = map(w, h, 7);
    let view = ImageView::new(&px, w, h).unwrap();
    for (radius, rect) in [(3usize, true), (8, true), (5, false)] {
        let settings = RefinePlane::new(radius, rect).unwrap();
        let mut plane = vec![0u8; w * h];
        let mut scratch = vec![0u32; refine_plane_buffer_len(w)];
        write_refine_plane(&view, settings, &mut plane, &mut scratch).unwrap();
        let mut differ = 0usize;
        let mut compared = 0usize;
        for (rx, ry, rw, rh) in [
            (0, 0, 60, 50),
            (40, 30, 70, 60),
            (90, 70, 60, 50),
            (17, 3, 41, 90),
        ] {
            let region = view.sub(rx, ry, rw, rh).unwrap();
            let mut out = vec![0u8; rw * rh];
            let mut hp = vec![0u32; highpass_buffer_len(rw)];
            let mut ov = ImageViewMut::new(&mut out, rw, rh).unwrap();
            highpass(&region, None, radius, &mut ov, &mut hp).unwrap();
            if rect {
                rectify(&mut ov);
            }
            for y in 0..rh {
                for x in 0..rw {
                    // Whole boxes: at least `radius` from the region's edges, or the region's
                    // edge is the map's.
                    let ok_x = (x >= radius || rx == 0) && (x + radius < rw || rx + rw == w);
                    let ok_y = (y >= radius || ry == 0) && (y + radius < rh || ry + rh == h);
                    if ok_x && ok_y {
                        compared += 1;
                        if out[y * rw + x] != plane[(ry + y) * w + rx + x] {
                            differ += 1;
                        }
                    }
                }
            }
        }
        assert!(compared > 5_000, "compared {compared}");
        assert_eq!(differ, 0, "radius {radius}, rectify {rect}");
    }
}

#[test]
fn plane_settings_are_validated() {
    assert!(RefinePlane::new(0, true).is_err());
    assert!(RefinePlane::new(1025, true).is_err());
    let s = RefinePlane::new(8, false).unwrap();
    assert_eq!((s.radius_px(), s.rectify()), (8, false));
    let px = map(20, 10, 1);
    let view = ImageView::new(&px, 20, 10).unwrap();
    let mut short = vec![0u8; 199];
    let mut scratch = vec![0u32; refine_plane_buffer_len(20)];
    assert!(write_refine_plane(&view, s, &mut short, &mut scratch).is_err());
    let mut out = vec![0u8; 200];
    assert!(write_refine_plane(&view, s, &mut out, &mut scratch[..10]).is_err());
}
