//! Rigid shapes: axis-aligned rectangles and circles ("Rigid Shape Bounds").

use glam::DVec2;

/// The bound of a rigid body, centred on the body's position. Shapes never rotate:
/// the chapter resolves collisions without angular impulses.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Shape {
    /// An axis-aligned rectangle, stored by its half extents.
    Rect { half: DVec2 },
    /// A circle of the given radius.
    Circle { radius: f64 },
}

impl Shape {
    /// A rectangle `width` x `height`.
    pub fn rect(width: f64, height: f64) -> Self {
        Shape::Rect {
            half: DVec2::new(width * 0.5, height * 0.5),
        }
    }

    /// A circle of radius `radius`.
    pub fn circle(radius: f64) -> Self {
        Shape::Circle { radius }
    }

    /// Half extents of the shape's axis-aligned bounding box.
    pub fn half_extents(&self) -> DVec2 {
        match *self {
            Shape::Rect { half } => half,
            Shape::Circle { radius } => DVec2::splat(radius),
        }
    }

    /// Full size: `[width, height]` for a rectangle, `[2r, 2r]` for a circle.
    pub fn size(&self) -> DVec2 {
        self.half_extents() * 2.0
    }

    /// Whether `point` lies strictly inside the shape centred at `centre` (the chapter's
    /// `containsPos`: points on the boundary are outside).
    pub fn contains(&self, centre: DVec2, point: DVec2) -> bool {
        let d = point - centre;
        match *self {
            Shape::Rect { half } => d.x.abs() < half.x && d.y.abs() < half.y,
            Shape::Circle { radius } => d.length_squared() < radius * radius,
        }
    }

    /// A short name for reports: "rect" or "circle".
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Rect { .. } => "rect",
            Shape::Circle { .. } => "circle",
        }
    }
}

/// An axis-aligned bounding box, used to reject far pairs before exact detection.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Aabb {
    pub min: DVec2,
    pub max: DVec2,
}

impl Aabb {
    pub fn of(shape: &Shape, centre: DVec2) -> Self {
        let h = shape.half_extents();
        Aabb {
            min: centre - h,
            max: centre + h,
        }
    }

    /// Whether the boxes overlap or touch.
    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.x <= other.max.x
            && other.min.x <= self.max.x
            && self.min.y <= other.max.y
            && other.min.y <= self.max.y
    }
}
