//! Background rocks: their sizes follow the configured distribution.

use orbfix_host::world::World;

#[test]
fn background_rocks_follow_their_size_distribution() {
    let world = World::new(13);
    let cfg = world.config().clone();
    let side = 200.0;
    let rocks = world.rocks_in(0.0, 0.0, side, side).expect("rect ok");
    let count = |d: f64| rocks.iter().filter(|r| r.diameter_m >= d).count() as f64;
    let expected = |d: f64| {
        cfg.rock_density_per_m2
            * (d.powf(-cfg.rock_exponent) - cfg.rock_d_max_m.powf(-cfg.rock_exponent))
            * side
            * side
    };
    for d in [0.2, 0.4, 0.8] {
        let (got, want) = (count(d), expected(d));
        assert!(
            (got - want).abs() < 4.0 * want.sqrt() + 0.02 * want,
            "N(>{d} m) = {got}, expected {want:.0}"
        );
    }
    assert!(rocks
        .iter()
        .all(|r| r.height_m > 0.0 && r.height_m < r.diameter_m && r.albedo_boost > 0.0));
}
