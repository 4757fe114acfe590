// The 32-byte dfs node (mod.rs DfsNode) and its loader, shared by the traversals of the
// dfs-sign, dfs-distance and threaded layouts. DFS_LEAF_TAG comes from mod.rs's LEAF_TAG.

// DfsNode. Inner: a = second child (threaded: the skip index), b = axis. Leaf: a = first tri, b = count<<2 | DFS_LEAF_TAG.
struct DfsNode {
    lo: vec3<f32>,
    a: u32,
    hi: vec3<f32>,
    b: u32,
}

fn dfs_load_node(i: u32) -> DfsNode {
    return dfs_node_from_words(node_word(2u * i), node_word(2u * i + 1u));
}

// A DfsNode from its two words (for traversals that load the words some other way).
fn dfs_node_from_words(a: vec4<u32>, b: vec4<u32>) -> DfsNode {
    return DfsNode(bitcast<vec3<f32>>(a.xyz), a.w, bitcast<vec3<f32>>(b.xyz), b.w);
}
