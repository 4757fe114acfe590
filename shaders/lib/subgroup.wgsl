// What the subgroup traversals (Layout::subgroup_wgsl) share; only subgroup kernels include
// it (gpu::shaders::trace_subgroup_source, render_subgroup_source), as they alone have the
// device's subgroup feature.

// The lanes are exactly 0..lanes-1 (so a lane's rank among the active lanes is its index, the
// one subgroupBroadcast reads) and at least `min_lanes` of them. Called by every lane.
fn subgroup_lanes_ok(lanes: u32, min_lanes: u32) -> bool {
    let ballot = subgroupBallot(true);
    let first = vec4<u32>(0u, 32u, 64u, 96u);
    let bits = min(max(vec4<u32>(lanes), first) - first, vec4<u32>(32u));
    let low = (vec4<u32>(1u) << (bits & vec4<u32>(31u))) - vec4<u32>(1u);
    let want = select(low, vec4<u32>(0xffffffffu), bits == vec4<u32>(32u));
    return all(ballot == want) && lanes >= min_lanes;
}

// The start of every subgroup traversal, called by every lane with whether its ray is valid:
// resets the work counters and sets traversal_done for an invalid ray. False when the
// traversal cannot go on: lanes it cannot address (subgroup_lanes_ok with `min_lanes`; left
// not done, the host traces them again) or no lane with a valid ray (all misses).
fn subgroup_start(valid: bool, min_lanes: u32) -> bool {
    traversal_start(valid);
    if !subgroup_lanes_ok(subgroupAdd(1u), min_lanes) {
        traversal_done = false;
        return false;
    }
    return subgroupAny(valid);
}
