//! Narrow-phase detection: depth and normal of a pair of shapes ("Extracting Collision
//! Information").
//!
//! Every function returns `None` when the shapes do not interpenetrate, and otherwise a
//! [`CollisionInfo`] whose normal points from the first shape toward the second: moving
//! the second shape by `depth` along `normal` (or the first by `-depth`) separates them.
//!
//! Departures from the chapter, each a defect of its code:
//! - a circle centre inside a rectangle is pushed out through the *nearest* of the four
//!   sides; the chapter measures the distance to the right and top sides only, so a circle
//!   near the left or bottom side was pushed out the far way;
//! - a circle centre exactly on a rectangle's edge is treated as inside (depth = radius,
//!   normal = that side's outward normal) instead of normalising a zero-length vector.

use glam::DVec2;

use super::shape::Shape;

/// Depth and normal of an interpenetration ("CollisionInfo").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CollisionInfo {
    /// How far the shapes overlap along `normal`; always > 0 for a reported collision.
    pub depth: f64,
    /// Unit vector from the first shape toward the second.
    pub normal: DVec2,
}

impl CollisionInfo {
    /// The same collision seen from the other shape.
    pub fn flipped(self) -> Self {
        CollisionInfo {
            depth: self.depth,
            normal: -self.normal,
        }
    }
}

/// Detects a collision between two shapes at the given centres.
pub fn collide(a: &Shape, pa: DVec2, b: &Shape, pb: DVec2) -> Option<CollisionInfo> {
    match (*a, *b) {
        (Shape::Rect { half: ha }, Shape::Rect { half: hb }) => collide_rects(pa, ha, pb, hb),
        (Shape::Circle { radius: ra }, Shape::Circle { radius: rb }) => {
            collide_circles(pa, ra, pb, rb)
        }
        (Shape::Rect { half }, Shape::Circle { radius }) => {
            collide_rect_circle(pa, half, pb, radius)
        }
        (Shape::Circle { radius }, Shape::Rect { half }) => {
            collide_rect_circle(pb, half, pa, radius).map(CollisionInfo::flipped)
        }
    }
}

/// Rectangle against rectangle: the axis of least penetration ("Modifying the
/// RigidRectangle Collision"). Ties go to the y axis, as in the chapter.
pub fn collide_rects(p1: DVec2, h1: DVec2, p2: DVec2, h2: DVec2) -> Option<CollisionInfo> {
    let d = p2 - p1;
    let x_depth = h1.x + h2.x - d.x.abs();
    if x_depth <= 0.0 {
        return None;
    }
    let y_depth = h1.y + h2.y - d.y.abs();
    if y_depth <= 0.0 {
        return None;
    }
    Some(if x_depth < y_depth {
        CollisionInfo {
            depth: x_depth,
            normal: DVec2::new(if d.x < 0.0 { -1.0 } else { 1.0 }, 0.0),
        }
    } else {
        CollisionInfo {
            depth: y_depth,
            normal: DVec2::new(0.0, if d.y < 0.0 { -1.0 } else { 1.0 }),
        }
    })
}

/// Circle against circle ("Modifying the Rigid Circle Collision"). Coincident centres
/// collide with depth `(r1 + r2) / 10` along +y, the chapter's convention, so relaxation
/// pulls them apart over a few iterations instead of dividing by zero.
pub fn collide_circles(p1: DVec2, r1: f64, p2: DVec2, r2: f64) -> Option<CollisionInfo> {
    let d = p2 - p1;
    let r_sum = r1 + r2;
    let dist_sq = d.length_squared();
    if dist_sq >= r_sum * r_sum {
        return None;
    }
    let dist = dist_sq.sqrt();
    if dist > 0.0 {
        Some(CollisionInfo {
            depth: r_sum - dist,
            normal: d / dist,
        })
    } else {
        Some(CollisionInfo {
            depth: r_sum / 10.0,
            normal: DVec2::Y,
        })
    }
}

/// Rectangle (first) against circle (second) ("Modifying the RigidShape Collision").
///
/// Outside the rectangle, the circle centre is compared with its clamp onto the rectangle.
/// Inside or on the boundary, the centre is pushed out through the nearest side.
pub fn collide_rect_circle(
    rect_pos: DVec2,
    half: DVec2,
    circle_pos: DVec2,
    radius: f64,
) -> Option<CollisionInfo> {
    let d = circle_pos - rect_pos;
    let inside = d.x.abs() <= half.x && d.y.abs() <= half.y;
    if inside {
        let (normal, to_side) = nearest_side(d, half);
        return Some(CollisionInfo {
            depth: radius + to_side,
            normal,
        });
    }
    let clamped = d.clamp(-half, half);
    let out = d - clamped;
    let dist_sq = out.length_squared();
    if dist_sq >= radius * radius {
        return None;
    }
    // Outside the closed rectangle, `out` has a non-zero component, so `dist` > 0.
    let dist = dist_sq.sqrt();
    Some(CollisionInfo {
        depth: radius - dist,
        normal: out / dist,
    })
}

/// The outward normal of the side nearest to `d` (a point inside the rectangle of half
/// extents `half`, relative to its centre) and the distance to that side.
///
/// The distance to the nearest vertical side is `half.x - |d.x|` and to the nearest
/// horizontal side `half.y - |d.y|`: all four sides are considered. Ties go to the y axis
/// and a centred point goes to the positive side, so the choice is deterministic.
pub fn nearest_side(d: DVec2, half: DVec2) -> (DVec2, f64) {
    let to_x = half.x - d.x.abs();
    let to_y = half.y - d.y.abs();
    if to_x < to_y {
        (DVec2::new(if d.x < 0.0 { -1.0 } else { 1.0 }, 0.0), to_x)
    } else {
        (DVec2::new(0.0, if d.y < 0.0 { -1.0 } else { 1.0 }), to_y)
    }
}

/// Signed distance between two shapes along a normal from the first toward the second:
/// positive when apart (the gap), negative when overlapping (minus the depth). Used by the
/// impulse solver's speculative contacts; agrees with [`collide`] when they overlap.
// Called for every candidate pair: inlined whatever codegen unit the solver lands in.
#[inline(always)]
pub fn separation(a: &Shape, pa: DVec2, b: &Shape, pb: DVec2) -> (f64, DVec2) {
    match (*a, *b) {
        (Shape::Rect { half: ha }, Shape::Rect { half: hb }) => {
            let d = pb - pa;
            let gap = d.abs() - (ha + hb);
            let sx = if d.x < 0.0 { -1.0 } else { 1.0 };
            let sy = if d.y < 0.0 { -1.0 } else { 1.0 };
            // Overlapping: the axis of least penetration, ties to y (as `collide_rects`);
            // apart: the axis of the larger gap. Selected without branches: touching
            // boxes sit at gaps of either sign by a rounding, which no branch predicts.
            let overlapping = (gap.x < 0.0) & (gap.y < 0.0);
            let on_x = (overlapping & (-gap.x < -gap.y)) | (!overlapping & (gap.x > gap.y));
            let pick = |x: f64, y: f64| if on_x { x } else { y };
            (pick(gap.x, gap.y), DVec2::new(pick(sx, 0.0), pick(0.0, sy)))
        }
        (Shape::Circle { radius: ra }, Shape::Circle { radius: rb }) => {
            let d = pb - pa;
            let dist = d.length();
            if dist > 0.0 {
                (dist - ra - rb, d / dist)
            } else {
                (-(ra + rb) / 10.0, DVec2::Y)
            }
        }
        (Shape::Rect { half }, Shape::Circle { radius }) => {
            rect_circle_separation(pa, half, pb, radius)
        }
        (Shape::Circle { radius }, Shape::Rect { half }) => {
            let (s, n) = rect_circle_separation(pb, half, pa, radius);
            (s, -n)
        }
    }
}

fn rect_circle_separation(
    rect_pos: DVec2,
    half: DVec2,
    circle_pos: DVec2,
    radius: f64,
) -> (f64, DVec2) {
    let d = circle_pos - rect_pos;
    if d.x.abs() <= half.x && d.y.abs() <= half.y {
        let (normal, to_side) = nearest_side(d, half);
        return (-(radius + to_side), normal);
    }
    let out = d - d.clamp(-half, half);
    let dist = out.length();
    (dist - radius, out / dist)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64) -> DVec2 {
        DVec2::new(x, y)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-12
    }

    #[test]
    fn rects_apart_do_not_collide() {
        // 10 x 10 boxes 10.5 apart on x: gap of 0.5.
        let h = v(5.0, 5.0);
        assert_eq!(collide_rects(v(0.0, 0.0), h, v(10.5, 0.0), h), None);
        // Touching edges are not a collision (strict overlap, as in the chapter).
        assert_eq!(collide_rects(v(0.0, 0.0), h, v(10.0, 0.0), h), None);
    }

    #[test]
    fn rects_pick_axis_of_least_penetration() {
        // Box A 10x10 at origin, box B 10x10 at (8, 3): x overlap 2, y overlap 7.
        let h = v(5.0, 5.0);
        let c = collide_rects(v(0.0, 0.0), h, v(8.0, 3.0), h).unwrap();
        assert!(close(c.depth, 2.0));
        assert_eq!(c.normal, v(1.0, 0.0));
        // Mirror on x: B to the left, the normal flips.
        let c = collide_rects(v(0.0, 0.0), h, v(-8.0, 3.0), h).unwrap();
        assert_eq!(c.normal, v(-1.0, 0.0));
        // B below by 9, offset 1 on x: y overlap 1 < x overlap 9.
        let c = collide_rects(v(0.0, 0.0), h, v(1.0, -9.0), h).unwrap();
        assert!(close(c.depth, 1.0));
        assert_eq!(c.normal, v(0.0, -1.0));
    }

    #[test]
    fn rects_with_coincident_centres_still_give_a_unit_normal() {
        let c = collide_rects(v(3.0, 3.0), v(2.0, 1.0), v(3.0, 3.0), v(2.0, 1.0)).unwrap();
        // x depth 4, y depth 2: y wins; d.y = 0 goes to +y.
        assert!(close(c.depth, 2.0));
        assert_eq!(c.normal, v(0.0, 1.0));
    }

    #[test]
    fn circles_hand_worked() {
        // r 3 and r 2, centres 4 apart on a 3-4-5 diagonal scaled: (0,0) to (2.4, 3.2).
        let c = collide_circles(v(0.0, 0.0), 3.0, v(2.4, 3.2), 2.0).unwrap();
        assert!(close(c.depth, 1.0));
        assert!(close(c.normal.x, 0.6) && close(c.normal.y, 0.8));
        assert_eq!(collide_circles(v(0.0, 0.0), 3.0, v(5.0, 0.0), 2.0), None);
        assert_eq!(collide_circles(v(0.0, 0.0), 3.0, v(6.0, 0.0), 2.0), None);
    }

    #[test]
    fn coincident_circles_follow_the_chapter_convention() {
        let c = collide_circles(v(1.0, 1.0), 3.0, v(1.0, 1.0), 2.0).unwrap();
        assert!(close(c.depth, 0.5));
        assert_eq!(c.normal, DVec2::Y);
        assert!(c.depth.is_finite() && c.normal.is_finite());
    }

    #[test]
    fn rect_circle_outside_the_side() {
        // Rect 10x4 at origin, circle r 1 at (0, 2.5): 0.5 above the top side.
        let c = collide_rect_circle(v(0.0, 0.0), v(5.0, 2.0), v(0.0, 2.5), 1.0).unwrap();
        assert!(close(c.depth, 0.5));
        assert_eq!(c.normal, v(0.0, 1.0));
    }

    #[test]
    fn rect_circle_outside_the_corner() {
        // Corner at (4, 2); circle centre at (4.75, 3): 0.75, 1 away, distance 1.25.
        let c = collide_rect_circle(v(0.0, 0.0), v(4.0, 2.0), v(4.75, 3.0), 1.5).unwrap();
        assert!(close(c.depth, 0.25));
        assert!(close(c.normal.x, 0.6) && close(c.normal.y, 0.8));
        assert_eq!(
            collide_rect_circle(v(0.0, 0.0), v(4.0, 2.0), v(4.75, 3.0), 1.25),
            None
        );
    }

    #[test]
    fn circle_centre_inside_near_each_of_the_four_sides() {
        // Rect 10x10 at origin, circle r 1. The chapter's test compared distances to the
        // positive sides only; each side must win when it is nearest.
        let h = v(5.0, 5.0);
        let cases = [
            (v(4.0, 0.5), v(1.0, 0.0), 2.0),   // right: 1 from the side
            (v(-4.0, 0.5), v(-1.0, 0.0), 2.0), // left
            (v(0.5, 4.5), v(0.0, 1.0), 1.5),   // top: 0.5 from the side
            (v(0.5, -4.5), v(0.0, -1.0), 1.5), // bottom
        ];
        for (centre, normal, depth) in cases {
            let c = collide_rect_circle(v(0.0, 0.0), h, centre, 1.0).unwrap();
            assert_eq!(c.normal, normal, "circle at {centre}");
            assert!(
                close(c.depth, depth),
                "circle at {centre}: depth {}",
                c.depth
            );
        }
    }

    #[test]
    fn circle_centre_exactly_on_the_edge_has_a_finite_normal() {
        let c = collide_rect_circle(v(0.0, 0.0), v(5.0, 2.0), v(-5.0, 0.0), 1.0).unwrap();
        assert_eq!(c.normal, v(-1.0, 0.0));
        assert!(close(c.depth, 1.0));
        let c = collide_rect_circle(v(0.0, 0.0), v(5.0, 2.0), v(1.0, -2.0), 1.0).unwrap();
        assert_eq!(c.normal, v(0.0, -1.0));
    }

    #[test]
    fn circle_against_rect_is_the_flipped_rect_against_circle() {
        let rect = Shape::rect(10.0, 4.0);
        let circle = Shape::circle(1.0);
        let a = collide(&rect, v(0.0, 0.0), &circle, v(0.0, 2.5)).unwrap();
        let b = collide(&circle, v(0.0, 2.5), &rect, v(0.0, 0.0)).unwrap();
        assert_eq!(a.depth, b.depth);
        assert_eq!(a.normal, -b.normal);
    }

    #[test]
    fn containment_is_strict() {
        let rect = Shape::rect(2.0, 2.0);
        assert!(rect.contains(v(0.0, 0.0), v(0.99, -0.99)));
        assert!(!rect.contains(v(0.0, 0.0), v(1.0, 0.0)));
        let circle = Shape::circle(1.0);
        assert!(circle.contains(v(0.0, 0.0), v(0.6, 0.79)));
        assert!(!circle.contains(v(0.0, 0.0), v(0.6, 0.8)));
    }

    #[test]
    fn separation_is_the_gap_apart_and_minus_the_depth_overlapping() {
        let h = Shape::rect(2.0, 2.0);
        let (s, n) = separation(&h, v(0.0, 0.0), &h, v(0.0, 2.5));
        assert!(close(s, 0.5) && n == v(0.0, 1.0));
        let (s, n) = separation(&h, v(0.0, 0.0), &h, v(-1.5, 0.2));
        let c = collide(&h, v(0.0, 0.0), &h, v(-1.5, 0.2)).unwrap();
        assert!(close(s, -c.depth) && n == c.normal);
        let (s, n) = separation(&Shape::circle(1.0), v(0.0, 0.0), &h, v(0.0, 3.0));
        assert!(close(s, 1.0) && n == v(0.0, 1.0));
    }

    mod properties {
        use super::*;
        use proptest::prelude::*;

        fn shape() -> impl Strategy<Value = Shape> {
            prop_oneof![
                (1e-3f64..1e3, 1e-3f64..1e3).prop_map(|(w, h)| Shape::rect(w, h)),
                (1e-3f64..1e3).prop_map(Shape::circle),
            ]
        }

        proptest! {
            /// Any reported collision has a finite positive depth and a unit normal, and
            /// moving the second shape by depth along the normal leaves at most a touch.
            #[test]
            fn collisions_are_finite_and_separable(
                a in shape(), b in shape(),
                ax in -1e3f64..1e3, ay in -1e3f64..1e3,
                dx in -2e3f64..2e3, dy in -2e3f64..2e3,
            ) {
                let pa = DVec2::new(ax, ay);
                let pb = pa + DVec2::new(dx, dy);
                // Coincident centres follow their own convention (tested above).
                prop_assume!(pa != pb);
                if let Some(c) = collide(&a, pa, &b, pb) {
                    prop_assert!(c.depth.is_finite() && c.depth > 0.0);
                    prop_assert!((c.normal.length() - 1.0).abs() < 1e-9);
                    let moved = pb + c.normal * (c.depth * (1.0 + 1e-9) + 1e-9);
                    let again = collide(&a, pa, &b, moved);
                    prop_assert!(again.is_none_or(|c2| c2.depth < 1e-6 * (1.0 + c.depth)),
                        "still overlapping by {:?}", again);
                }
            }
        }
    }
}
