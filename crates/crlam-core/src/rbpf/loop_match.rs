//! The loop-closure search: a scan matched over a wide window against points mapped long ago.
//!
//! Loop closing (`crlam.slam.loop_closing`) keeps, beside the particles, the endpoints of every
//! processed scan at the poses of a pose graph. When the robot comes back near old nodes, the
//! current scan is searched against the endpoints of those nodes only: a window as wide as the
//! drift the travelled path allows (metres and tens of degrees), searched by the branch and
//! bound of [`super::correlative`] over a likelihood field of the old endpoints' cells. The
//! old nodes' points are given in world coordinates; nothing of the particles' maps is read,
//! so the search finds the place even when no particle's map is right there.

use crate::error::{CrlamError, Result};
use crate::grid::GridGeometry;
use crate::pose::Pose;
use crate::rbpf::correlative::{
    depth_for_window, field_rect, search_excluding, CorrelativeMatch, CorrelativeSettings,
    LikelihoodField,
};

/// Most world points a search reads (a map's worth of endpoints, far beyond one neighbourhood).
pub const MAX_LOOP_POINTS: usize = 4_000_000;

/// Searches the window of `settings` around `guess` for the robot pose at which `endpoints`
/// (robot frame, m) fall best on the cells of `world_points` (world frame, m) on a grid of
/// `resolution` m cells with its origin at (0, 0); with `exclude` (a point and a radius, m), the
/// best pose farther than the radius from the point (see [`search_excluding`]).
///
/// Only the cells the endpoints can reach from the window are built (the field of
/// [`field_rect`]); points outside them are ignored.
pub fn match_against_points(
    world_points: &[[f64; 2]],
    resolution: f64,
    endpoints: &[[f64; 2]],
    guess: Pose,
    settings: &CorrelativeSettings,
    exclude: Option<([f64; 2], f64)>,
) -> Result<CorrelativeMatch> {
    settings.validate()?;
    crate::grid::check_pose(guess)?;
    if world_points.len() > MAX_LOOP_POINTS {
        return Err(CrlamError::Shape(format!(
            "{} map points exceed the loop search's limit of {MAX_LOOP_POINTS}",
            world_points.len()
        )));
    }
    let geometry = GridGeometry::new([0.0, 0.0], resolution)?;
    let reach = endpoints
        .iter()
        .filter(|e| e[0].is_finite() && e[1].is_finite())
        .map(|e| e[0].hypot(e[1]))
        .fold(resolution, f64::max);
    let rect = field_rect(&geometry, guess, reach, settings)?;
    let mut occupied = vec![false; rect.n_cells()];
    for p in world_points {
        if !(p[0].is_finite() && p[1].is_finite()) {
            continue;
        }
        let (ix, iy) = geometry.cell_of(p[0], p[1]);
        let (x, y) = (ix - rect.ix0, iy - rect.iy0);
        if x >= 0 && y >= 0 && x < rect.nx && y < rect.ny {
            occupied[(y * rect.nx + x) as usize] = true;
        }
    }
    let w = (settings.linear_window / resolution).ceil() as i64;
    let field = LikelihoodField::new(geometry, rect, &occupied, depth_for_window(w))?;
    search_excluding(&field, endpoints, guess, settings, exclude)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::compose;

    /// A room with walls and a few boxes, as points every 2 cm.
    fn room() -> Vec<[f64; 2]> {
        let mut pts = Vec::new();
        let mut segment = |a: [f64; 2], b: [f64; 2]| {
            let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / 0.02).ceil() as usize;
            for i in 0..=n {
                let t = i as f64 / n as f64;
                pts.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        };
        segment([0.0, 0.0], [12.0, 0.0]);
        segment([12.0, 0.0], [12.0, 8.0]);
        segment([12.0, 8.0], [0.0, 8.0]);
        segment([0.0, 8.0], [0.0, 0.0]);
        segment([3.0, 2.0], [4.0, 2.0]);
        segment([4.0, 2.0], [4.0, 3.5]);
        segment([8.0, 5.0], [9.5, 6.0]);
        pts
    }

    /// The room's points seen from `pose`, in the robot frame (every 4th point).
    fn seen_from(points: &[[f64; 2]], pose: Pose) -> Vec<[f64; 2]> {
        let (s, c) = pose[2].sin_cos();
        points
            .iter()
            .step_by(4)
            .map(|p| {
                let (dx, dy) = (p[0] - pose[0], p[1] - pose[1]);
                [c * dx + s * dy, -s * dx + c * dy]
            })
            .collect()
    }

    fn settings(linear: f64, angular: f64) -> CorrelativeSettings {
        CorrelativeSettings {
            linear_window: linear,
            angular_window: angular,
            penalty: 0.0,
            min_score: 0.0,
            min_gain: 0.0,
        }
    }

    #[test]
    fn a_far_off_guess_is_brought_back() {
        let map = room();
        let truth = [6.0, 4.0, 0.3];
        let scan = seen_from(&map, truth);
        // Two metres and 14 degrees off: far beyond a hill climb's reach.
        let guess = compose(truth, [1.5, -1.3, -0.25]);
        let m = match_against_points(&map, 0.05, &scan, guess, &settings(2.5, 0.4), None).unwrap();
        assert!(
            (m.pose[0] - truth[0]).hypot(m.pose[1] - truth[1]) < 0.08,
            "{m:?}"
        );
        assert!((m.pose[2] - truth[2]).abs() < 0.02, "{m:?}");
        assert!(m.explained > 0.8, "{m:?}");
    }

    #[test]
    fn a_room_has_no_second_place_but_a_bare_corridor_has() {
        let map = room();
        let truth = [6.0, 4.0, 0.3];
        let scan = seen_from(&map, truth);
        let s = settings(2.0, 0.3);
        let best = match_against_points(&map, 0.05, &scan, truth, &s, None).unwrap();
        let elsewhere =
            match_against_points(&map, 0.05, &scan, truth, &s, Some(([6.0, 4.0], 0.5))).unwrap();
        assert!(
            elsewhere.explained < 0.6 * best.explained,
            "{best:?} {elsewhere:?}"
        );
        assert!((elsewhere.pose[0] - 6.0).hypot(elsewhere.pose[1] - 4.0) > 0.5);
        // Two long parallel walls: a shift along them explains as much.
        let mut corridor = Vec::new();
        for i in 0..=2000 {
            let x = i as f64 * 0.02;
            corridor.push([x, 0.0]);
            corridor.push([x, 3.0]);
        }
        let pose = [20.0, 1.5, 0.0];
        let scan = seen_from(&corridor, pose);
        let best = match_against_points(&corridor, 0.05, &scan, pose, &s, None).unwrap();
        let elsewhere =
            match_against_points(&corridor, 0.05, &scan, pose, &s, Some(([20.0, 1.5], 0.5)))
                .unwrap();
        assert!(
            elsewhere.explained > 0.9 * best.explained,
            "{best:?} {elsewhere:?}"
        );
    }

    #[test]
    fn points_elsewhere_explain_nothing() {
        let map: Vec<[f64; 2]> = room().iter().map(|p| [p[0] + 100.0, p[1]]).collect();
        let scan = seen_from(&room(), [6.0, 4.0, 0.0]);
        let m = match_against_points(
            &map,
            0.05,
            &scan,
            [6.0, 4.0, 0.0],
            &settings(1.0, 0.2),
            None,
        )
        .unwrap();
        assert_eq!(m.explained, 0.0);
    }

    #[test]
    fn too_many_points_are_refused() {
        let many = vec![[0.0, 0.0]; MAX_LOOP_POINTS + 1];
        let e = match_against_points(
            &many,
            0.1,
            &[[1.0, 0.0]],
            [0.0; 3],
            &settings(1.0, 0.2),
            None,
        );
        assert!(e.is_err());
    }
}
