"""The hand-written CDR of markers, meshes and states equals what rclpy serializes."""

import io

import numpy as np
from PIL import Image
from rclpy.serialization import deserialize_message, serialize_message

from hair_sim import DEFAULT_DT, HairSimulator, load_hairstyle, paths
from hair_sim.render import HairRenderer
from hair_sim.sinks.cdr import same_bytes_but_padding
from hair_sim.sinks.markers import (build_marker_array, marker_array_cdr, marker_geometry,
                                    MarkerLayout, MAX_POINTS)
from hair_sim.sinks.mesh_msg import (build_hair_mesh, build_hair_mesh_topology, hair_mesh_cdr,
                                     hair_mesh_topology_cdr, hair_state_cdr)


def render(sim, viewpoint=None):
    """Return the U-shape mesh of a simulator's state."""
    return HairRenderer.for_simulator(sim).mesh_of(sim, viewpoint)


def moving_sim(style='thesis_long', **params):
    """Return a simulator a little into a head turn."""
    sim = HairSimulator(load_hairstyle(paths.shipped_style(style)), **params)
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    sim.set_head_pose(0.2, [0.01, 0.02, 0.0], [0, 0, 0.2, 0.98])
    for _ in range(30):
        sim.step(DEFAULT_DT)
    return sim


def test_marker_array_fast_path_is_byte_exact():
    """Fast CDR == serialize_message(slow message), and deserializes to it, culled or not."""
    from visualization_msgs.msg import MarkerArray
    sim = moving_sim()
    R, p = sim.head_pose
    for viewpoint in (None, [0.8, 0.0, 0.1]):
        mesh = render(sim, viewpoint)
        layout = MarkerLayout(sim.strips.n_strips, mesh.tris_per_strip,
                              None if viewpoint else mesh)
        geo = marker_geometry(mesh, R, p, layout)
        fast, pad = marker_array_cdr(geo, mesh.texture_id, mesh.texture_png, 'head', 7, 42,
                                     with_padding=True)
        slow = build_marker_array(geo, mesh.texture_id, mesh.texture_png, 'head', 7, 42)
        assert same_bytes_but_padding(fast, serialize_message(slow), pad)
        assert deserialize_message(fast, MarkerArray) == slow


def test_marker_contents_follow_the_jazzy_rules():
    """Points a multiple of 3, one UV each, < 65k per marker, PNG texture, same triangles."""
    sim = HairSimulator(load_hairstyle(paths.shipped_style('thesis_long')).with_strip_count(180))
    sim.set_head_pose(0.0, [0, 0, 0], [0, 0, 0, 1])
    sim.step(DEFAULT_DT)
    R, p = sim.head_pose
    mesh = render(sim)
    layout = MarkerLayout(sim.strips.n_strips, mesh.tris_per_strip, mesh)
    geo = marker_geometry(mesh, R, p, layout)
    arr = build_marker_array(geo, mesh.texture_id, mesh.texture_png, 'head', 1, 2)
    assert len(arr.markers) >= 2
    total = 0
    for m in arr.markers:
        assert m.type == m.TRIANGLE_LIST and m.header.frame_id == 'head'
        assert len(m.points) % 3 == 0 and len(m.points) < MAX_POINTS
        assert len(m.uv_coordinates) == len(m.points)
        assert m.texture_resource.startswith('embedded://') and m.texture.format == 'png'
        assert Image.open(io.BytesIO(bytes(m.texture.data))).mode == 'RGBA'
        total += len(m.points)
    pts = np.concatenate([np.array([(q.x, q.y, q.z) for q in m.points]) for m in arr.markers])
    head_frame = (mesh.vertices.astype(np.float64) - p) @ R
    np.testing.assert_allclose(pts, head_frame[mesh.indices.reshape(-1)], atol=1e-12)
    # culling keeps every marker's triangle count: culled strips collapse, not vanish
    culled = render(sim, [0.8, 0.0, 0.0])
    assert culled.n_strips < mesh.n_strips
    geo2 = marker_geometry(culled, R, p, layout)
    assert [len(g[0]) for g in geo2] == [len(g[0]) for g in geo]
    assert all(len(g[1]) == len(g[0]) for g in geo2)
    kept = culled.strip_ids[0]                         # a drawn strip: the same points
    nt3 = 3 * mesh.tris_per_strip
    pts1 = np.concatenate([g[0] for g in geo])[kept * nt3:(kept + 1) * nt3]
    pts2 = np.concatenate([g[0] for g in geo2])[kept * nt3:(kept + 1) * nt3]
    np.testing.assert_array_equal(pts1, pts2)


def test_hair_mesh_topology_and_state_fast_paths_are_byte_exact():
    """The CDR of HairMesh, HairMeshTopology and HairState equals rclpy's serialization."""
    from hair_sim_msgs.msg import HairMesh, HairMeshTopology, HairState
    sim = moving_sim()
    renderer = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    for viewpoint in (None, [0.8, 0.0, 0.0]):
        mesh = renderer.mesh(sim.pos, R, p, viewpoint)
        fast, pad = hair_mesh_cdr(mesh.vertices, mesh.strip_ids, 7, 'world', 3, 4,
                                  with_padding=True)
        slow = build_hair_mesh(mesh.vertices, mesh.strip_ids, 7, 'world', 3, 4)
        assert same_bytes_but_padding(fast, serialize_message(slow), pad)
        back = deserialize_message(fast, HairMesh)
        assert back == slow and back.topology_id == 7
        np.testing.assert_array_equal(np.asarray(back.vertices, np.float32),
                                      mesh.vertices.reshape(-1))
    topology = renderer.topology()
    fast, pad = hair_mesh_topology_cdr(topology, 7, 'world', 3, 4, with_padding=True)
    slow = build_hair_mesh_topology(topology, 7, 'world', 3, 4)
    assert same_bytes_but_padding(fast, serialize_message(slow), pad)
    back = deserialize_message(fast, HairMeshTopology)
    assert back == slow and bytes(back.texture_png) == topology.texture_png
    np.testing.assert_array_equal(np.asarray(back.indices, np.uint32),
                                  topology.indices.reshape(-1))
    st, pad = hair_state_cdr(sim.pos, True, 0.00123, 'world', 5, 6, with_padding=True)
    msg = deserialize_message(st, HairState)
    assert (msg.n_strands, msg.vertices_per_strand) == sim.pos.shape[:2]
    assert msg.sleeping and msg.step_time == 0.00123
    np.testing.assert_array_equal(np.asarray(msg.positions, np.float32),
                                  sim.pos.astype(np.float32).reshape(-1))
    ref = HairState(n_strands=sim.pos.shape[0], vertices_per_strand=sim.pos.shape[1],
                    positions=sim.pos.astype(np.float32).reshape(-1), sleeping=True,
                    step_time=0.00123)
    ref.header.stamp.sec, ref.header.stamp.nanosec, ref.header.frame_id = 5, 6, 'world'
    assert same_bytes_but_padding(st, serialize_message(ref), pad)
    assert msg == ref


def test_marker_encoder_matches_the_slow_path_frame_after_frame():
    """The encoder rewrites only stamps and points; every frame equals the slow path."""
    from visualization_msgs.msg import MarkerArray
    from hair_sim.sinks.markers import MarkerEncoder
    sim = moving_sim()
    full = render(sim)
    layout = MarkerLayout(sim.strips.n_strips, full.tris_per_strip, full)
    enc = MarkerEncoder(layout, full.texture_id, full.texture_png,
                        'head')
    for k, viewpoint in enumerate((None, [0.8, 0.0, 0.0], None)):
        sim.step(DEFAULT_DT)
        R, p = sim.head_pose
        mesh = render(sim, viewpoint)
        fast = enc.encode(mesh, R, p, 100 + k, 7)
        slow = build_marker_array(marker_geometry(mesh, R, p, layout), mesh.texture_id,
                                  mesh.texture_png, 'head', 100 + k, 7)
        assert deserialize_message(fast, MarkerArray) == slow


def test_head_marker_bytes_deserialize_to_the_display_mesh():
    """head_markers: a skin-coloured TRIANGLE_LIST of the GLB, head frame, frame-locked."""
    from visualization_msgs.msg import Marker, MarkerArray
    from hair_sim import load_head, paths
    from hair_sim.sinks.markers import head_marker_cdr, HEAD_COLOR, MAX_POINTS
    head = load_head(paths.shipped_head('default_adult'))
    v, t = head.display_mesh()
    arr = deserialize_message(head_marker_cdr(v, t, 'head', 5, 6), MarkerArray)
    points = np.array([[p.x, p.y, p.z] for m in arr.markers for p in m.points])
    np.testing.assert_array_equal(points, v[t.reshape(-1)])
    for m in arr.markers:
        assert m.type == Marker.TRIANGLE_LIST and m.frame_locked and m.ns == 'head'
        assert m.header.frame_id == 'head' and m.header.stamp.sec == 5
        assert len(m.points) % 3 == 0 and len(m.points) < MAX_POINTS
        assert np.allclose([m.color.r, m.color.g, m.color.b, m.color.a], HEAD_COLOR)
        assert not m.texture_resource and not m.uv_coordinates
    # a mesh over one marker's limit is split on triangle boundaries, nothing lost
    big_t = np.tile(t, (3, 1))
    arr = deserialize_message(head_marker_cdr(v, big_t, 'head', 0, 0), MarkerArray)
    assert len(arr.markers) == 2 and [m.id for m in arr.markers] == [0, 1]
    assert sum(len(m.points) for m in arr.markers) == 3 * len(big_t)


def mesh_from_topology(topology, strip_ids):
    """Return (indices, uvs) of the strips strip_ids as HairMeshTopology's comment says."""
    nv, nt = topology.verts_per_strip, topology.tris_per_strip
    tris, uvs = [], []
    for k, s in enumerate(strip_ids):
        o = topology.strip_offsets
        assert o[s + 1] - o[s] == nt
        tris.append(topology.indices[o[s]:o[s + 1]].astype(np.int64) - (s - k) * nv)
        uvs.append(topology.uvs[s * nv:(s + 1) * nv])
    return np.concatenate(tris), np.concatenate(uvs)


def test_a_mesh_is_its_topology_and_its_vertices():
    """Topology (per style) + vertices and strip_ids (per frame) make the mesh, culled too."""
    sim = moving_sim()
    renderer = HairRenderer.for_simulator(sim)
    R, p = sim.head_pose
    topology = renderer.topology()
    assert topology is renderer.topology()              # built once per renderer
    drawn = []
    for viewpoint in (None, [0.8, 0.0, 0.0], p + R @ [0.8, 0.0, 0.0]):    # from the front
        mesh = renderer.mesh(sim.pos, R, p, viewpoint)
        drawn.append(mesh.n_strips)
        indices, uvs = mesh_from_topology(topology, mesh.strip_ids)
        np.testing.assert_array_equal(indices, mesh.indices)
        np.testing.assert_array_equal(uvs, mesh.uvs)
        assert len(mesh.vertices) == mesh.n_strips * topology.verts_per_strip
        assert indices.max() < len(mesh.vertices)
    assert drawn[0] == topology.n_strips and 0 < min(drawn[1:]) < topology.n_strips
    assert topology.texture_png == mesh.texture_png and topology.texture_id == mesh.texture_id
