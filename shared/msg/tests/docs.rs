//! docs/messages.md must state the true size of every payload.

use core::mem::size_of;
use dkrrt_msg::*;

#[test]
fn the_service_table_matches_the_code() {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/messages.md"))
        .expect("docs/messages.md exists");
    let expect: [(&str, &str, usize); 10] = [
        (<RobotState as bus::Topic>::SERVICE, "RobotState", size_of::<RobotState>()),
        (<TorqueCommand as bus::Topic>::SERVICE, "TorqueCommand", size_of::<TorqueCommand>()),
        (<Trajectory as bus::Topic>::SERVICE, "Trajectory", size_of::<Trajectory>()),
        (<Goal as bus::Topic>::SERVICE, "Goal", size_of::<Goal>()),
        (<Heartbeat as bus::Topic>::SERVICE, "Heartbeat", size_of::<Heartbeat>()),
        (<DebrisObservation as bus::Topic>::SERVICE, "DebrisObservation", size_of::<DebrisObservation>()),
        (<DebrisForecast as bus::Topic>::SERVICE, "DebrisForecast", size_of::<DebrisForecast>()),
        (<PlanStatus as bus::Topic>::SERVICE, "PlanStatus", size_of::<PlanStatus>()),
        (<PredictorProgress as bus::Topic>::SERVICE, "PredictorProgress", size_of::<PredictorProgress>()),
        (<DepthImage as bus::Topic>::SERVICE, "DepthImage", size_of::<DepthImage>()),
    ];
    for (service, ty, size) in expect {
        let row = format!("| `{service}` | `{ty}` | {size} |");
        assert!(doc.contains(&row), "docs/messages.md lacks the row starting {row}");
    }
    assert!(doc.contains(&format!("[[JerkSegment; {MAX_SEGMENTS}]; {NJ}]")));
}
