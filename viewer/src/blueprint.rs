//! The default layout: the world's 2D view with a fixed camera on the scene's bounds, the
//! step's figures as plots beside it, the text log of commands below them. Several worlds
//! share the one 2D view (their roots side by side or overlaid) and every plot, with the
//! plots of how far they drift apart after the step's.
//!
//! The SDK's layout builder has no visual bounds for 2D views, so the blueprint is written
//! as the viewer stores it: one archetype per container and view, under fixed ids.

use re_sdk::external::re_log_types::{BlueprintActivationCommand, LogMsg};
use re_sdk::{RecordingStream, RecordingStreamBuilder, RecordingStreamResult};
use re_sdk_types::blueprint::archetypes::{
    Background, ContainerBlueprint, PanelBlueprint, TimePanelBlueprint, ViewBlueprint,
    ViewContents, ViewportBlueprint, VisualBounds2D,
};
use re_sdk_types::blueprint::components::{
    AutoLayout, AutoViews, BackgroundKind, ColumnShare, ContainerKind, IncludedContent, PanelState,
    QueryExpression, RootContainer, RowShare, ViewClass,
};
use re_sdk_types::components::Name;
use re_sdk_types::datatypes::{Bool, Float32, Range1D, Range2D};

use crate::draw;

/// The plots: entity path under `stats/`, title.
/// Next to the step time, the live accuracy estimates (no reference needed): deepest
/// penetration, energy change per step, the solver's residual, passes actually run.
pub const PLOTS: [(&str, &str); 9] = [
    ("step_ms", "step time (ms)"),
    ("contacts", "contacts"),
    ("solver_passes", "solver passes run"),
    ("deepest_penetration", "deepest penetration"),
    ("energy_change", "energy change per step"),
    ("residual", "solver residual (units)"),
    ("kinetic_energy", "kinetic energy"),
    ("particles", "particles"),
    ("bytes_per_frame", "bytes per frame"),
];

enum Node {
    View {
        class: &'static str,
        name: String,
        origin: String,
        bounds: Option<([f64; 2], [f64; 2])>,
    },
    Container {
        kind: ContainerKind,
        children: Vec<Node>,
        shares: Vec<f32>,
        columns: Option<u32>,
    },
}

/// Ids are fixed (derived from the node's place in the tree), so a re-sent layout replaces
/// the previous one rather than adding to it.
fn id(path: &[usize]) -> uuid::Uuid {
    let mut v: u128 = 0x5249_434f_4348_4554_0000_0000_0000_0000; // "RICOCHET"
    for (depth, i) in path.iter().enumerate() {
        v ^= ((*i as u128) + 1) << (8 * depth);
    }
    uuid::Uuid::from_u128(v)
}

fn log_node(
    rec: &RecordingStream,
    node: &Node,
    path: &mut Vec<usize>,
) -> RecordingStreamResult<String> {
    let uuid = id(path);
    match node {
        Node::View {
            class,
            name,
            origin,
            bounds,
        } => {
            let bp = format!("view/{uuid}");
            rec.log(
                format!("{bp}/ViewContents"),
                &ViewContents::new([QueryExpression("$origin/**".into())]),
            )?;
            rec.log(
                bp.clone(),
                &ViewBlueprint::new(ViewClass((*class).into()))
                    .with_display_name(Name(name.clone().into()))
                    .with_space_origin(origin.as_str()),
            )?;
            if let Some((x, y)) = bounds {
                // The chapter draws on a dark canvas: its additive colours need one.
                let [r, g, b, a] = draw::BACKGROUND;
                rec.log(
                    format!("{bp}/Background"),
                    &Background::new(BackgroundKind::SolidColor).with_color(
                        re_sdk_types::components::Color::from_unmultiplied_rgba(r, g, b, a),
                    ),
                )?;
                rec.log(
                    format!("{bp}/VisualBounds2D"),
                    &VisualBounds2D::new(Range2D {
                        x_range: Range1D(*x),
                        y_range: Range1D(*y),
                    }),
                )?;
            }
            Ok(bp)
        }
        Node::Container {
            kind,
            children,
            shares,
            columns,
        } => {
            let mut contents = Vec::new();
            for (i, child) in children.iter().enumerate() {
                path.push(i);
                contents.push(IncludedContent(log_node(rec, child, path)?.into()));
                path.pop();
            }
            let mut arch = ContainerBlueprint::new(*kind).with_contents(contents);
            if !shares.is_empty() {
                arch = match kind {
                    ContainerKind::Vertical => {
                        arch.with_row_shares(shares.iter().map(|s| RowShare(Float32(*s))))
                    }
                    _ => arch.with_col_shares(shares.iter().map(|s| ColumnShare(Float32(*s)))),
                };
            }
            if let Some(c) = columns {
                arch = arch.with_grid_columns(re_sdk_types::blueprint::components::GridColumns(
                    (*c).into(),
                ));
            }
            let bp = format!("container/{uuid}");
            rec.log(bp.clone(), &arch)?;
            Ok(bp)
        }
    }
}

/// What the layout shows: the 2D view's title and camera, the plots beside it.
pub struct Views {
    /// The 2D view's title: `world (<scene>)` for one world.
    pub title: String,
    /// The scene's bounds, or those of all worlds as placed in the view, in world units.
    pub bounds: [[f64; 2]; 2],
    /// Each plot's entity path (its series are it or its children) and title.
    pub plots: Vec<(String, String)>,
}

impl Views {
    /// One world: its scene's name and bounds, the step's figures.
    pub fn one_world(bounds: [[f64; 2]; 2], scene: &str) -> Views {
        Views {
            title: format!("world ({scene})"),
            bounds,
            plots: PLOTS
                .iter()
                .map(|(path, title)| (format!("stats/{path}"), (*title).to_string()))
                .collect(),
        }
    }
}

fn layout(views: &Views) -> Node {
    let plots = views
        .plots
        .iter()
        .map(|(path, title)| Node::View {
            class: "TimeSeries",
            name: title.clone(),
            origin: format!("/{path}"),
            bounds: None,
        })
        .collect();
    Node::Container {
        kind: ContainerKind::Horizontal,
        shares: vec![3.0, 2.0],
        columns: None,
        children: vec![
            Node::View {
                class: "2D",
                name: views.title.clone(),
                origin: "/world".into(),
                bounds: Some(draw::camera(views.bounds)),
            },
            Node::Container {
                kind: ContainerKind::Vertical,
                shares: vec![3.0, 1.0],
                columns: None,
                children: vec![
                    Node::Container {
                        kind: ContainerKind::Grid,
                        shares: Vec::new(),
                        columns: Some(2),
                        children: plots,
                    },
                    Node::View {
                        class: "TextLog",
                        name: "commands".into(),
                        origin: "/events".into(),
                        bounds: None,
                    },
                ],
            },
        ],
    }
}

/// Sends the layout of `views` to `rec` and makes it the active one.
pub fn send(
    rec: &RecordingStream,
    app_id: &'static str,
    views: &Views,
) -> RecordingStreamResult<()> {
    let (bp, storage) = RecordingStreamBuilder::new(app_id)
        .recording_id(uuid::Uuid::new_v4().to_string())
        .blueprint()
        .memory()?;
    bp.set_time_sequence("blueprint", 0);
    let root = log_node(&bp, &layout(views), &mut Vec::new())?;
    let root_id = root.trim_start_matches("container/");
    let root_uuid = uuid::Uuid::parse_str(root_id).expect("container ids are uuids");
    bp.log(
        "viewport",
        &ViewportBlueprint::new()
            .with_root_container(RootContainer(root_uuid.into()))
            .with_auto_layout(AutoLayout(Bool(false)))
            .with_auto_views(AutoViews(Bool(false))),
    )?;
    // The views get the whole window; the side and time panels open with a click.
    for panel in ["blueprint_panel", "selection_panel"] {
        bp.log(
            panel,
            &PanelBlueprint::new().with_state(PanelState::Collapsed),
        )?;
    }
    bp.log(
        "time_panel",
        &TimePanelBlueprint::new().with_state(PanelState::Collapsed),
    )?;
    let msgs: Vec<LogMsg> = storage.take(); // flushes
    let Some(LogMsg::SetStoreInfo(info)) = msgs.first() else {
        unreachable!("a blueprint stream starts with its store info")
    };
    let blueprint_id = info.info.store_id.clone();
    rec.send_blueprint(
        msgs,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}
