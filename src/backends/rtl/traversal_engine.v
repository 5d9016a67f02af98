// The traversal engine: the closest-hit search of src/kernel/bvh.hpp (walk_binary over the scene's binary BVH, the
// primitive tests of SceneLeaf) as hardware, with many rays in flight. Its arithmetic is the generated units'
// (tools/hardware/units.py --engine-units, which `define the unit modules named below); this file is the control.
//
// Each ray lives in a context: its ray and reciprocal direction, the closest hit so far, a stack and where its walk
// stands. Every clock two schedulers each pick a context (the lowest-numbered) that has a test to issue: one a box
// test (an inner node's two children, read from the node memory's two ports and tested by two box units at once,
// or a root's box), the other a primitive test (from the primitive memory). The read takes one clock and the test
// enters its unit the clock after; the result comes back through the unit's pipeline, tagged with the context in a
// FIFO (the units keep order), and moves that context on. A context thus walks exactly as walk_binary does: the
// root's box first, then at an inner node both children's boxes, the nearer entered first and the other pushed (the
// first child where the entries are equal), a leaf's primitives one after another, each tested against the closest
// hit so far, so that hits at equal distances resolve as in the kernel. The many contexts keep the pipelines busy
// meanwhile, in the manner of the multithreaded ray processors (Woop, Schmittler and Slusallek 2005; TRaX).
//
// A mesh instance (intersect_instance) takes the ray into the mesh's space (the instance-ray unit), gives it its own
// reciprocal (the setup unit, shared with entering rays, which wait meanwhile), and walks the mesh's tree from its
// root on the same stack, above the scene's entries; when the stack is back down to where the instance began, the
// scene's leaf goes on with its next primitive. A triangle hit there names the instance and the mesh's triangle.
//
// Scene memory: nodes as {count, left_first, hi.z, hi.y, hi.x, lo.z, lo.y, lo.x} (BvhNode), the scene's and after
// them the meshes' (their left_first moved to where they are); primitives as {kind, 14 fields} (kind 0: a sphere as
// a moving one, fields center0, radius, velocity, time0; 1: a triangle, p0, edge1, edge2; 2: a quad, corner, normal,
// du, dv, u_extent, v_extent; 3: a mesh instance, its world-to-mesh rows and translation and its mesh's root node;
// 4: a constant medium, its boundary's place and piece count, its density term and which of the ray's free-flight
// distances is its; 5: a sphere of a medium's boundary, center and radius), the scene's, then the meshes' triangles,
// then the media's boundary pieces. Written through the load ports before rays are sent. Left out: the random draw of
// a medium's free-flight distance (see below).
//
// A constant medium (intersect_medium) is walked like a leaf of its own: its boundary's pieces one after another
// (a sphere's two crossings of the ray's line from the crossings unit, a face's one from the triangle or quad unit
// over the whole line), then the medium unit clips the stretch inside to (0, closest) and either adds its optical
// depth (a shadow ray) or compares it with the free-flight distance the ray brought for that medium. That distance,
// neg_inv_density log(1 - u) of the ray's own random number, depends on the ray's sample, its bounce and the
// medium's index only, never on the walk: the host draws it beside the ray (up to four media), so the hash of the
// random stream and the logarithm are the part of the intersect stage that is not in this engine.
`default_nettype none
module traversal_engine #(
  parameter W = `PT_ENGINE_WORD,      // bits of a fixed-point value
  parameter CONTEXT_BITS = 6,         // 2^CONTEXT_BITS rays in flight
  parameter NODE_BITS = 16,           // node memory: 2^NODE_BITS entries
  parameter PRIMITIVE_BITS = 16,      // primitive memory: 2^PRIMITIVE_BITS entries
  parameter NODE_WIDTH = 6 * W + 64,
  parameter PRIMITIVE_WIDTH = 14 * W + 3
) (
  input wire clk,
  input wire reset,
  input wire node_write,
  input wire [NODE_BITS-1:0] node_address,
  input wire [NODE_WIDTH-1:0] node_data,
  input wire primitive_write,
  input wire [PRIMITIVE_BITS-1:0] primitive_address,
  input wire [PRIMITIVE_WIDTH-1:0] primitive_data,
  // A ray enters when ray_valid and ray_ready are both high at a clock edge.
  input wire ray_valid,
  output wire ray_ready,
  input wire [31:0] ray_id,
  input wire signed [W-1:0] origin_x, origin_y, origin_z,
  input wire signed [W-1:0] direction_x, direction_y, direction_z,
  input wire signed [W-1:0] ray_time,
  input wire signed [W-1:0] t_max,
  input wire ray_shadow,              // a shadow ray: media add their optical depth instead of scattering it
  input wire signed [W-1:0] medium_distance_0, medium_distance_1, medium_distance_2, medium_distance_3,
  // One finished ray per clock at most: hit_found says whether anything was hit before t_max.
  output reg hit_valid,
  output reg [31:0] hit_id,
  output reg hit_found,
  output reg signed [W-1:0] hit_t, hit_b1, hit_b2,
  output reg [31:0] hit_primitive,
  output reg hit_in_mesh,             // hit_triangle names the mesh triangle's place in primitive memory
  output reg [31:0] hit_triangle,
  output reg signed [W-1:0] hit_optical_depth,
  output reg [15:0] hit_box_tests,
  output reg [15:0] hit_primitive_tests,
  // Which units take a test this clock (for utilisation).
  output wire box_issue,               // a root's box test, or the first of an inner node's two
  output wire second_box_issue,        // the second
  output wire sphere_issue,
  output wire triangle_issue,
  output wire quad_issue,
  output wire instance_issue,
  output wire [15:0] context_count,    // rays in flight at most
  output wire medium_issue
);
  localparam CONTEXTS = 1 << CONTEXT_BITS;
  localparam DEPTH = 128;  // kBvhMaxDepth for the scene's walk and as much for a mesh's above it
  localparam FIFO_BITS = 7;  // tags in flight per unit: more than the deepest unit's latency
  localparam [3:0] FREE = 0, SETUP = 1, ROOT = 2, CHILDREN = 3, PRIMITIVE = 5, ISSUING = 6, WAITING = 7, DONE = 8,
                   MESH_ROOT = 9, MESH_PRIMITIVE = 10, MEDIUM_PIECE = 11, MEDIUM_END = 12;
  localparam [2:0] KIND_SPHERE = 0, KIND_TRIANGLE = 1, KIND_QUAD = 2, KIND_INSTANCE = 3, KIND_MEDIUM = 4, KIND_BOUNDARY_SPHERE = 5;
  localparam signed [W-1:0] LARGEST = {1'b0, {(W-1){1'b1}}};

  reg [NODE_WIDTH-1:0] nodes [0:(1 << NODE_BITS) - 1];
  reg [PRIMITIVE_WIDTH-1:0] primitives [0:(1 << PRIMITIVE_BITS) - 1];

  // ---- Contexts ----
  reg [3:0] state [0:CONTEXTS-1];
  reg [31:0] id [0:CONTEXTS-1];
  reg signed [W-1:0] ox [0:CONTEXTS-1], oy [0:CONTEXTS-1], oz [0:CONTEXTS-1];
  reg signed [W-1:0] dx [0:CONTEXTS-1], dy [0:CONTEXTS-1], dz [0:CONTEXTS-1];
  reg signed [W-1:0] rtime [0:CONTEXTS-1];
  reg signed [W-1:0] ix [0:CONTEXTS-1], iy [0:CONTEXTS-1], iz [0:CONTEXTS-1];
  reg signed [W-1:0] closest [0:CONTEXTS-1];
  reg [31:0] child0 [0:CONTEXTS-1], child1 [0:CONTEXTS-1];  // the inner node's children: index + 1, left_first
  reg [31:0] next_primitive [0:CONTEXTS-1], end_primitive [0:CONTEXTS-1];
  reg [95:0] header0 [0:CONTEXTS-1], header1 [0:CONTEXTS-1];  // tested children as {index, count, left_first}
  reg [7:0] depth [0:CONTEXTS-1];
  // In a mesh instance: the ray in the mesh's space, the instance, the mesh's root, the depth its walk began at,
  // and the mesh leaf's triangles.
  reg in_mesh [0:CONTEXTS-1];
  reg signed [W-1:0] lx [0:CONTEXTS-1], ly [0:CONTEXTS-1], lz [0:CONTEXTS-1];
  reg signed [W-1:0] ldx [0:CONTEXTS-1], ldy [0:CONTEXTS-1], ldz [0:CONTEXTS-1];
  reg signed [W-1:0] lix [0:CONTEXTS-1], liy [0:CONTEXTS-1], liz [0:CONTEXTS-1];
  reg [31:0] mesh_root [0:CONTEXTS-1];
  reg [7:0] mesh_base [0:CONTEXTS-1];
  reg [31:0] next_triangle [0:CONTEXTS-1], end_triangle [0:CONTEXTS-1];
  reg found_in_mesh [0:CONTEXTS-1];
  // Media: the ray's kind and free-flight distances, the optical depth summed, and the medium being walked (its
  // pieces, the crossings so far, its density term and which distance is its).
  reg shadow [0:CONTEXTS-1];
  reg signed [W-1:0] distance0 [0:CONTEXTS-1], distance1 [0:CONTEXTS-1], distance2 [0:CONTEXTS-1], distance3 [0:CONTEXTS-1];
  reg signed [W-1:0] optical_depth [0:CONTEXTS-1];
  reg in_medium [0:CONTEXTS-1];
  reg [31:0] next_piece [0:CONTEXTS-1], end_piece [0:CONTEXTS-1];
  reg signed [W-1:0] crossing_first [0:CONTEXTS-1], crossing_last [0:CONTEXTS-1], neg_inv_density [0:CONTEXTS-1];
  reg [1:0] medium_slot [0:CONTEXTS-1];
  reg [31:0] found_triangle [0:CONTEXTS-1];
  reg [95:0] stack [0:CONTEXTS*DEPTH-1];
  reg found [0:CONTEXTS-1];
  reg signed [W-1:0] found_t [0:CONTEXTS-1], found_b1 [0:CONTEXTS-1], found_b2 [0:CONTEXTS-1];
  reg [31:0] found_primitive [0:CONTEXTS-1];
  reg [15:0] box_tests [0:CONTEXTS-1], primitive_tests [0:CONTEXTS-1];

  // ---- Picks: the lowest-numbered context with a box test to issue, with a primitive test, free, and done ----
  reg box_pick_valid, primitive_pick_valid, free_valid, done_valid;
  reg [CONTEXT_BITS-1:0] box_pick, primitive_pick, free_context, done_context;
  integer k;
  always @* begin
    box_pick_valid = 0; primitive_pick_valid = 0; free_valid = 0; done_valid = 0;
    box_pick = 0; primitive_pick = 0; free_context = 0; done_context = 0;
    for (k = CONTEXTS - 1; k >= 0; k = k - 1) begin
      if (state[k] == ROOT || state[k] == CHILDREN || state[k] == MESH_ROOT) begin
        box_pick_valid = 1; box_pick = k[CONTEXT_BITS-1:0];
      end
      if (state[k] == PRIMITIVE || state[k] == MESH_PRIMITIVE || state[k] == MEDIUM_PIECE || state[k] == MEDIUM_END) begin
        primitive_pick_valid = 1; primitive_pick = k[CONTEXT_BITS-1:0];
      end
      if (state[k] == FREE) begin free_valid = 1; free_context = k[CONTEXT_BITS-1:0]; end
      if (state[k] == DONE) begin done_valid = 1; done_context = k[CONTEXT_BITS-1:0]; end
    end
  end
  // The setup unit takes a ray into an instance before a new ray.
  wire instance_valid;
  assign ray_ready = free_valid && !reset && !instance_valid;
  wire accept = ray_valid && ray_ready;

  // ---- Stage A -> B: the memory reads for the picked contexts ----
  reg bb_valid, b_valid;
  reg [CONTEXT_BITS-1:0] bb_context, b_context;
  reg [3:0] bb_kind, b_kind;
  reg [31:0] bb_index0, bb_index1;
  reg [NODE_WIDTH-1:0] node_read0, node_read1;
  reg [PRIMITIVE_WIDTH-1:0] primitive_read;
  wire [31:0] pick_node0 = state[box_pick] == ROOT ? 32'd0 : state[box_pick] == MESH_ROOT ? mesh_root[box_pick] : child0[box_pick];
  wire [31:0] pick_node1 = child1[box_pick];
  wire [31:0] pick_primitive = state[primitive_pick] == MESH_PRIMITIVE ? next_triangle[primitive_pick]
                             : state[primitive_pick] == MEDIUM_PIECE ? next_piece[primitive_pick] : next_primitive[primitive_pick];

  // ---- Units ----
  // Stage B drives the units from the memory reads and the contexts' rays: the box units from the box scheduler's
  // context (cb), the others from the primitive scheduler's (c).
  wire [CONTEXT_BITS-1:0] c = b_context;
  wire [CONTEXT_BITS-1:0] cb = bb_context;
  wire b_piece = b_valid && b_kind == MEDIUM_PIECE;
  wire b_primitive = b_valid && (b_kind == PRIMITIVE || b_kind == MESH_PRIMITIVE || b_kind == MEDIUM_PIECE);
  assign medium_issue = b_valid && b_kind == MEDIUM_END;
  wire b_box = bb_valid;
  wire b_pair = bb_valid && bb_kind == CHILDREN;
  // A mesh leaf holds triangles only.
  wire [2:0] b_primitive_kind = b_kind == MESH_PRIMITIVE ? KIND_TRIANGLE : primitive_read[14*W +: 3];
  // A medium's boundary piece is met anywhere along the ray's line.
  wire signed [W-1:0] test_min = b_piece ? -LARGEST : zero, test_max = b_piece ? LARGEST : closest[c];
  wire crossings_issue = b_primitive && b_primitive_kind == KIND_BOUNDARY_SPHERE;
  wire begin_medium = b_primitive && b_primitive_kind == KIND_MEDIUM;
  assign context_count = CONTEXTS;
  assign box_issue = b_box;
  assign second_box_issue = b_pair;
  assign sphere_issue = b_primitive && b_primitive_kind == KIND_SPHERE;
  assign triangle_issue = b_primitive && b_primitive_kind == KIND_TRIANGLE;
  assign quad_issue = b_primitive && b_primitive_kind == KIND_QUAD;
  assign instance_issue = b_primitive && b_primitive_kind == KIND_INSTANCE;
  function automatic signed [W-1:0] field(input [PRIMITIVE_WIDTH-1:0] record, input integer index);
    field = record[index*W +: W];
  endfunction
  function automatic signed [W-1:0] bound(input [NODE_WIDTH-1:0] record, input integer index);
    bound = record[index*W +: W];
  endfunction
  // The ray the context walks with: the world's, or in a mesh instance the mesh space's.
  wire signed [W-1:0] ray_ox = in_mesh[c] ? lx[c] : ox[c], ray_oy = in_mesh[c] ? ly[c] : oy[c], ray_oz = in_mesh[c] ? lz[c] : oz[c];
  wire signed [W-1:0] ray_dx = in_mesh[c] ? ldx[c] : dx[c], ray_dy = in_mesh[c] ? ldy[c] : dy[c], ray_dz = in_mesh[c] ? ldz[c] : dz[c];
  wire signed [W-1:0] box_ox = in_mesh[cb] ? lx[cb] : ox[cb], box_oy = in_mesh[cb] ? ly[cb] : oy[cb], box_oz = in_mesh[cb] ? lz[cb] : oz[cb];
  wire signed [W-1:0] box_ix = in_mesh[cb] ? lix[cb] : ix[cb], box_iy = in_mesh[cb] ? liy[cb] : iy[cb], box_iz = in_mesh[cb] ? liz[cb] : iz[cb];
  // A negative reciprocal meets the hi plane first (make_box_ray).
  wire neg_x = box_ix[W-1], neg_y = box_iy[W-1], neg_z = box_iz[W-1];
  wire signed [W-1:0] zero = 0;
  wire signed [W-1:0] ray_distance = medium_slot[c] == 0 ? distance0[c] : medium_slot[c] == 1 ? distance1[c] : medium_slot[c] == 2 ? distance2[c] : distance3[c];

  wire signed [W-1:0] local_ox, local_oy, local_oz, local_dx, local_dy, local_dz;
  `PT_INSTANCE_RAY_UNIT instance_ray(.clk(clk), .in_valid(instance_issue), .row0_x(field(primitive_read, 0)), .row0_y(field(primitive_read, 1)),
                                     .row0_z(field(primitive_read, 2)), .row1_x(field(primitive_read, 3)), .row1_y(field(primitive_read, 4)),
                                     .row1_z(field(primitive_read, 5)), .row2_x(field(primitive_read, 6)), .row2_y(field(primitive_read, 7)),
                                     .row2_z(field(primitive_read, 8)), .translation_x(field(primitive_read, 9)),
                                     .translation_y(field(primitive_read, 10)), .translation_z(field(primitive_read, 11)), .origin_x(ox[c]),
                                     .origin_y(oy[c]), .origin_z(oz[c]), .direction_x(dx[c]), .direction_y(dy[c]), .direction_z(dz[c]),
                                     .out_valid(instance_valid), .local_origin_x(local_ox), .local_origin_y(local_oy), .local_origin_z(local_oz),
                                     .local_direction_x(local_dx), .local_direction_y(local_dy), .local_direction_z(local_dz));
  wire setup_valid;
  wire signed [W-1:0] setup_x, setup_y, setup_z;
  `PT_RAY_SETUP_UNIT ray_setup(.clk(clk), .in_valid(accept || instance_valid), .direction_x(instance_valid ? local_dx : direction_x),
                               .direction_y(instance_valid ? local_dy : direction_y), .direction_z(instance_valid ? local_dz : direction_z),
                               .out_valid(setup_valid), .inv_x(setup_x), .inv_y(setup_y), .inv_z(setup_z));
  wire box_valid, box_hit, second_box_valid, second_box_hit;
  wire signed [W-1:0] box_entry, second_box_entry;
  `PT_BOX_UNIT box(.clk(clk), .in_valid(b_box), .inv_direction_x(box_ix), .inv_direction_y(box_iy), .inv_direction_z(box_iz),
                   .origin_term_x(box_ox), .origin_term_y(box_oy), .origin_term_z(box_oz),
                   .near_bound_x(bound(node_read0, neg_x ? 3 : 0)), .near_bound_y(bound(node_read0, neg_y ? 4 : 1)),
                   .near_bound_z(bound(node_read0, neg_z ? 5 : 2)), .far_bound_x(bound(node_read0, neg_x ? 0 : 3)),
                   .far_bound_y(bound(node_read0, neg_y ? 1 : 4)), .far_bound_z(bound(node_read0, neg_z ? 2 : 5)),
                   .t_min(zero), .t_max(closest[cb]), .out_valid(box_valid), .hit(box_hit), .t_entry(box_entry));
  `PT_BOX_UNIT second_box(.clk(clk), .in_valid(b_pair), .inv_direction_x(box_ix), .inv_direction_y(box_iy), .inv_direction_z(box_iz),
                          .origin_term_x(box_ox), .origin_term_y(box_oy), .origin_term_z(box_oz),
                          .near_bound_x(bound(node_read1, neg_x ? 3 : 0)), .near_bound_y(bound(node_read1, neg_y ? 4 : 1)),
                          .near_bound_z(bound(node_read1, neg_z ? 5 : 2)), .far_bound_x(bound(node_read1, neg_x ? 0 : 3)),
                          .far_bound_y(bound(node_read1, neg_y ? 1 : 4)), .far_bound_z(bound(node_read1, neg_z ? 2 : 5)),
                          .t_min(zero), .t_max(closest[cb]), .out_valid(second_box_valid), .hit(second_box_hit),
                          .t_entry(second_box_entry));
  wire sphere_valid, sphere_hit;
  wire signed [W-1:0] sphere_t, sphere_b1, sphere_b2;
  `PT_SPHERE_UNIT sphere(.clk(clk), .in_valid(sphere_issue), .center0_x(field(primitive_read, 0)), .center0_y(field(primitive_read, 1)),
                         .center0_z(field(primitive_read, 2)), .radius(field(primitive_read, 3)), .velocity_x(field(primitive_read, 4)),
                         .velocity_y(field(primitive_read, 5)), .velocity_z(field(primitive_read, 6)), .time0(field(primitive_read, 7)),
                         .ray_time(rtime[c]), .origin_x(ox[c]), .origin_y(oy[c]), .origin_z(oz[c]), .direction_x(dx[c]), .direction_y(dy[c]),
                         .direction_z(dz[c]), .t_min(zero), .t_max(closest[c]), .out_valid(sphere_valid), .hit(sphere_hit), .t(sphere_t),
                         .b1(sphere_b1), .b2(sphere_b2));
  wire triangle_valid, triangle_hit;
  wire signed [W-1:0] triangle_t, triangle_b1, triangle_b2;
  `PT_TRIANGLE_UNIT triangle(.clk(clk), .in_valid(triangle_issue), .p0_x(field(primitive_read, 0)), .p0_y(field(primitive_read, 1)),
                             .p0_z(field(primitive_read, 2)), .edge1_x(field(primitive_read, 3)), .edge1_y(field(primitive_read, 4)),
                             .edge1_z(field(primitive_read, 5)), .edge2_x(field(primitive_read, 6)), .edge2_y(field(primitive_read, 7)),
                             .edge2_z(field(primitive_read, 8)), .origin_x(ray_ox), .origin_y(ray_oy), .origin_z(ray_oz), .direction_x(ray_dx),
                             .direction_y(ray_dy), .direction_z(ray_dz), .t_min(test_min), .t_max(test_max), .out_valid(triangle_valid),
                             .hit(triangle_hit), .t(triangle_t), .b1(triangle_b1), .b2(triangle_b2));
  wire quad_valid, quad_hit;
  wire signed [W-1:0] quad_t, quad_b1, quad_b2;
  `PT_QUAD_UNIT quad(.clk(clk), .in_valid(quad_issue), .corner_x(field(primitive_read, 0)), .corner_y(field(primitive_read, 1)),
                     .corner_z(field(primitive_read, 2)), .normal_x(field(primitive_read, 3)), .normal_y(field(primitive_read, 4)),
                     .normal_z(field(primitive_read, 5)), .du_x(field(primitive_read, 6)), .du_y(field(primitive_read, 7)),
                     .du_z(field(primitive_read, 8)), .dv_x(field(primitive_read, 9)), .dv_y(field(primitive_read, 10)),
                     .dv_z(field(primitive_read, 11)), .u_extent(field(primitive_read, 12)), .v_extent(field(primitive_read, 13)),
                     .origin_x(ox[c]), .origin_y(oy[c]), .origin_z(oz[c]), .direction_x(dx[c]), .direction_y(dy[c]), .direction_z(dz[c]),
                     .t_min(test_min), .t_max(test_max), .out_valid(quad_valid), .hit(quad_hit), .t(quad_t), .b1(quad_b1), .b2(quad_b2));
  wire crossings_valid, crossings_hit;
  wire signed [W-1:0] crossings_near, crossings_far;
  `PT_CROSSINGS_UNIT crossings(.clk(clk), .in_valid(crossings_issue), .origin_x(ox[c]), .origin_y(oy[c]), .origin_z(oz[c]), .direction_x(dx[c]),
                               .direction_y(dy[c]), .direction_z(dz[c]), .center_x(field(primitive_read, 0)), .center_y(field(primitive_read, 1)),
                               .center_z(field(primitive_read, 2)), .radius(field(primitive_read, 3)), .out_valid(crossings_valid),
                               .hit(crossings_hit), .near(crossings_near), .far(crossings_far));
  wire medium_valid, medium_hit;
  wire signed [W-1:0] medium_t, medium_depth;
  `PT_MEDIUM_UNIT medium_end(.clk(clk), .in_valid(medium_issue), .first(crossing_first[c]), .last(crossing_last[c]), .t_max(closest[c]),
                             .distance(ray_distance), .neg_inv_density(neg_inv_density[c]), .optical_depth(optical_depth[c]),
                         .shadow({{(W-1){1'b0}}, shadow[c]}), .out_valid(medium_valid), .hit(medium_hit), .t(medium_t),
                         .optical_depth_out(medium_depth));

  // ---- Tag FIFOs: which context (and for boxes which child) each result in a unit's pipeline belongs to ----
  reg [CONTEXT_BITS+1:0] setup_tags [0:(1 << FIFO_BITS) - 1], box_tags [0:(1 << FIFO_BITS) - 1];
  reg [CONTEXT_BITS+1:0] sphere_tags [0:(1 << FIFO_BITS) - 1], triangle_tags [0:(1 << FIFO_BITS) - 1], quad_tags [0:(1 << FIFO_BITS) - 1];
  reg [CONTEXT_BITS+1:0] instance_tags [0:(1 << FIFO_BITS) - 1];
  reg [CONTEXT_BITS+1:0] crossings_tags [0:(1 << FIFO_BITS) - 1], medium_tags [0:(1 << FIFO_BITS) - 1];
  reg [FIFO_BITS-1:0] crossings_in, crossings_out, medium_in, medium_out;
  wire [CONTEXT_BITS-1:0] crossings_context = crossings_tags[crossings_out][CONTEXT_BITS-1:0];
  wire [CONTEXT_BITS-1:0] medium_context = medium_tags[medium_out][CONTEXT_BITS-1:0];
  reg [FIFO_BITS-1:0] setup_in, setup_out, box_in, box_out, sphere_in, sphere_out, triangle_in, triangle_out, quad_in, quad_out;
  reg [FIFO_BITS-1:0] instance_in, instance_out;
  wire [CONTEXT_BITS-1:0] setup_context = setup_tags[setup_out][CONTEXT_BITS-1:0];
  wire setup_for_instance = setup_tags[setup_out][CONTEXT_BITS];
  wire [CONTEXT_BITS-1:0] instance_context = instance_tags[instance_out][CONTEXT_BITS-1:0];
  wire [CONTEXT_BITS-1:0] box_context = box_tags[box_out][CONTEXT_BITS-1:0];
  wire box_root = box_tags[box_out][CONTEXT_BITS];  // a root's test (else an inner node's pair)
  wire [CONTEXT_BITS-1:0] sphere_context = sphere_tags[sphere_out][CONTEXT_BITS-1:0];
  wire [CONTEXT_BITS-1:0] triangle_context = triangle_tags[triangle_out][CONTEXT_BITS-1:0];
  wire [CONTEXT_BITS-1:0] quad_context = quad_tags[quad_out][CONTEXT_BITS-1:0];

  // Going to a node whose header is known: a leaf's primitives (a mesh leaf's triangles, where the walk is in a
  // mesh), or an inner node's two children's boxes. `mesh` says which tree the node is in: the caller's, since a
  // walk leaving a mesh clears in_mesh in the same clock.
  task automatic enter_node(input [CONTEXT_BITS-1:0] x, input [95:0] header, input mesh);
    if (header[63:32] != 0 && mesh) begin
      next_triangle[x] <= header[31:0];
      end_triangle[x] <= header[31:0] + header[63:32];
      state[x] <= MESH_PRIMITIVE;
    end else if (header[63:32] != 0) begin
      next_primitive[x] <= header[31:0];
      end_primitive[x] <= header[31:0] + header[63:32];
      state[x] <= PRIMITIVE;
    end else begin
      child0[x] <= header[95:64] + 1;
      child1[x] <= header[31:0];
      state[x] <= CHILDREN;
    end
  endtask
  task automatic enter(input [CONTEXT_BITS-1:0] x, input [95:0] header);
    enter_node(x, header, in_mesh[x]);
  endtask
  function automatic [CONTEXT_BITS+6:0] stack_slot(input [CONTEXT_BITS-1:0] x, input [7:0] level);
    stack_slot = {x, level[6:0]};
  endfunction
  // The scene's walk goes on from the stack, or ends.
  task automatic scene_pop(input [CONTEXT_BITS-1:0] x);
    if (depth[x] == 0) begin
      state[x] <= DONE;
    end else begin
      depth[x] <= depth[x] - 1;
      enter_node(x, stack[stack_slot(x, depth[x] - 1)], 0);
    end
  endtask
  // The scene's leaf goes on after a primitive: its next one, or the stack.
  task automatic scene_leaf_next(input [CONTEXT_BITS-1:0] x);
    if (next_primitive[x] + 1 != end_primitive[x]) begin
      next_primitive[x] <= next_primitive[x] + 1;
      state[x] <= PRIMITIVE;
    end else begin
      scene_pop(x);
    end
  endtask
  // A mesh's walk goes on from the stack, or, back at the depth it began at, ends: the scene's leaf goes on.
  task automatic mesh_pop(input [CONTEXT_BITS-1:0] x);
    if (depth[x] == mesh_base[x]) begin
      in_mesh[x] <= 0;
      scene_leaf_next(x);
    end else begin
      depth[x] <= depth[x] - 1;
      enter(x, stack[stack_slot(x, depth[x] - 1)]);
    end
  endtask
  task automatic pop(input [CONTEXT_BITS-1:0] x);
    if (in_mesh[x]) mesh_pop(x);
    else scene_pop(x);
  endtask
  // A boundary piece's crossings widen the medium's stretch; then its next piece, or the medium unit.
  task automatic piece_done(input [CONTEXT_BITS-1:0] x, input crosses, input signed [W-1:0] near, input signed [W-1:0] far);
    if (crosses) begin
      crossing_first[x] <= near < crossing_first[x] ? near : crossing_first[x];
      crossing_last[x] <= far > crossing_last[x] ? far : crossing_last[x];
    end
    if (next_piece[x] + 1 != end_piece[x]) begin
      next_piece[x] <= next_piece[x] + 1;
      state[x] <= MEDIUM_PIECE;
    end else begin
      state[x] <= MEDIUM_END;
    end
  endtask
  // A primitive's result: the closest hit narrows where it was hit, then the leaf's next primitive or the stack.
  task automatic primitive_done(input [CONTEXT_BITS-1:0] x, input hit, input signed [W-1:0] t, input signed [W-1:0] b1,
                                input signed [W-1:0] b2);
    if (hit) begin
      closest[x] <= t;
      found[x] <= 1;
      found_t[x] <= t;
      found_b1[x] <= b1;
      found_b2[x] <= b2;
      found_primitive[x] <= next_primitive[x];
      found_in_mesh[x] <= in_mesh[x];
      found_triangle[x] <= next_triangle[x];
    end
    if (in_mesh[x]) begin
      if (next_triangle[x] + 1 != end_triangle[x]) begin
        next_triangle[x] <= next_triangle[x] + 1;
        state[x] <= MESH_PRIMITIVE;
      end else begin
        mesh_pop(x);
      end
    end else begin
      scene_leaf_next(x);
    end
  endtask

  reg [95:0] near_header, far_header;
  always @(posedge clk) begin
    if (reset) begin
      for (k = 0; k < CONTEXTS; k = k + 1) state[k] <= FREE;
      b_valid <= 0;
      bb_valid <= 0;
      hit_valid <= 0;
      setup_in <= 0; setup_out <= 0; box_in <= 0; box_out <= 0; sphere_in <= 0; sphere_out <= 0; instance_in <= 0; instance_out <= 0;
      crossings_in <= 0; crossings_out <= 0; medium_in <= 0; medium_out <= 0;
      triangle_in <= 0; triangle_out <= 0; quad_in <= 0; quad_out <= 0;
    end else begin
      if (node_write) nodes[node_address] <= node_data;
      if (primitive_write) primitives[primitive_address] <= primitive_data;

      // A new ray: its context, and its reciprocal direction into the setup unit.
      if (accept) begin
        state[free_context] <= SETUP;
        id[free_context] <= ray_id;
        ox[free_context] <= origin_x; oy[free_context] <= origin_y; oz[free_context] <= origin_z;
        dx[free_context] <= direction_x; dy[free_context] <= direction_y; dz[free_context] <= direction_z;
        rtime[free_context] <= ray_time;
        closest[free_context] <= t_max;
        depth[free_context] <= 0;
        in_mesh[free_context] <= 0;
        in_medium[free_context] <= 0;
        shadow[free_context] <= ray_shadow;
        optical_depth[free_context] <= 0;
        distance0[free_context] <= medium_distance_0; distance1[free_context] <= medium_distance_1;
        distance2[free_context] <= medium_distance_2; distance3[free_context] <= medium_distance_3;
        found[free_context] <= 0;
        box_tests[free_context] <= 0;
        primitive_tests[free_context] <= 0;
        setup_tags[setup_in] <= {2'b0, free_context};
        setup_in <= setup_in + 1;
      end
      // A ray taken into an instance: its reciprocal next, then the mesh's root.
      if (instance_valid) begin
        lx[instance_context] <= local_ox; ly[instance_context] <= local_oy; lz[instance_context] <= local_oz;
        ldx[instance_context] <= local_dx; ldy[instance_context] <= local_dy; ldz[instance_context] <= local_dz;
        instance_out <= instance_out + 1;
        setup_tags[setup_in] <= {2'b01, instance_context};
        setup_in <= setup_in + 1;
      end
      if (setup_valid) begin
        if (setup_for_instance) begin
          lix[setup_context] <= setup_x; liy[setup_context] <= setup_y; liz[setup_context] <= setup_z;
          in_mesh[setup_context] <= 1;
          mesh_base[setup_context] <= depth[setup_context];
          state[setup_context] <= MESH_ROOT;
        end else begin
          ix[setup_context] <= setup_x; iy[setup_context] <= setup_y; iz[setup_context] <= setup_z;
          state[setup_context] <= ROOT;
        end
        setup_out <= setup_out + 1;
      end

      // Stage A: the picked contexts' node and primitive reads.
      bb_valid <= box_pick_valid;
      if (box_pick_valid) begin
        bb_context <= box_pick;
        bb_kind <= state[box_pick];
        bb_index0 <= pick_node0;
        bb_index1 <= pick_node1;
        node_read0 <= nodes[pick_node0[NODE_BITS-1:0]];
        node_read1 <= nodes[pick_node1[NODE_BITS-1:0]];
        state[box_pick] <= ISSUING;
      end
      b_valid <= primitive_pick_valid;
      if (primitive_pick_valid) begin
        b_context <= primitive_pick;
        b_kind <= state[primitive_pick];
        primitive_read <= primitives[pick_primitive[PRIMITIVE_BITS-1:0]];
        state[primitive_pick] <= ISSUING;
      end

      // Stage B: the test goes into its unit (the unit's inputs are wired above); the context waits for it.
      if (b_valid) begin
        if (medium_issue) begin
          medium_tags[medium_in] <= {2'b0, c};
          medium_in <= medium_in + 1;
          state[c] <= WAITING;
        end else if (b_primitive) begin
          primitive_tests[c] <= primitive_tests[c] + 1;
          if (!begin_medium) state[c] <= WAITING;
          if (sphere_issue) begin sphere_tags[sphere_in] <= {2'b0, c}; sphere_in <= sphere_in + 1; end
          if (triangle_issue) begin triangle_tags[triangle_in] <= {2'b0, c}; triangle_in <= triangle_in + 1; end
          if (quad_issue) begin quad_tags[quad_in] <= {2'b0, c}; quad_in <= quad_in + 1; end
          if (crossings_issue) begin crossings_tags[crossings_in] <= {2'b0, c}; crossings_in <= crossings_in + 1; end
          // A medium: its boundary's pieces next, the stretch inside empty so far.
          if (begin_medium) begin
            in_medium[c] <= 1;
            next_piece[c] <= field(primitive_read, 0);
            end_piece[c] <= field(primitive_read, 0) + field(primitive_read, 1);
            neg_inv_density[c] <= field(primitive_read, 2);
            medium_slot[c] <= field(primitive_read, 3);
            crossing_first[c] <= LARGEST;
            crossing_last[c] <= -LARGEST;
            state[c] <= MEDIUM_PIECE;
          end
          if (instance_issue) begin
            instance_tags[instance_in] <= {2'b0, c};
            instance_in <= instance_in + 1;
            mesh_root[c] <= field(primitive_read, 12);
          end
        end
      end
      if (bb_valid) begin
        box_tests[cb] <= box_tests[cb] + (b_pair ? 2 : 1);
        box_tags[box_in] <= {1'b0, !b_pair, cb};
        box_in <= box_in + 1;
        header0[cb] <= {bb_index0, node_read0[6*W+32 +: 32], node_read0[6*W +: 32]};
        header1[cb] <= {bb_index1, node_read1[6*W+32 +: 32], node_read1[6*W +: 32]};
        state[cb] <= WAITING;
      end

      // Box results: the root's decides whether the walk starts; an inner node's pair where it goes.
      if (box_valid) begin
        box_out <= box_out + 1;
        if (box_root) begin
          // A mesh's root missed: the instance is done (mesh_pop at the depth it began at).
          if (box_hit) enter(box_context, header0[box_context]);
          else if (in_mesh[box_context]) mesh_pop(box_context);
          else state[box_context] <= DONE;
        end else if (box_hit && second_box_hit) begin
          // The nearer child next, the other pushed; the first where the entries are equal (walk_binary).
          if (second_box_entry < box_entry) begin
            near_header = header1[box_context]; far_header = header0[box_context];
          end else begin
            near_header = header0[box_context]; far_header = header1[box_context];
          end
          stack[stack_slot(box_context, depth[box_context])] <= far_header;
          depth[box_context] <= depth[box_context] + 1;
          enter(box_context, near_header);
        end else if (box_hit) begin
          enter(box_context, header0[box_context]);
        end else if (second_box_hit) begin
          enter(box_context, header1[box_context]);
        end else begin
          pop(box_context);
        end
      end

      if (sphere_valid) begin
        sphere_out <= sphere_out + 1;
        primitive_done(sphere_context, sphere_hit, sphere_t, sphere_b1, sphere_b2);
      end
      if (triangle_valid) begin
        triangle_out <= triangle_out + 1;
        if (in_medium[triangle_context]) piece_done(triangle_context, triangle_hit, triangle_t, triangle_t);
        else primitive_done(triangle_context, triangle_hit, triangle_t, triangle_b1, triangle_b2);
      end
      if (quad_valid) begin
        quad_out <= quad_out + 1;
        if (in_medium[quad_context]) piece_done(quad_context, quad_hit, quad_t, quad_t);
        else primitive_done(quad_context, quad_hit, quad_t, quad_b1, quad_b2);
      end
      if (crossings_valid) begin
        crossings_out <= crossings_out + 1;
        piece_done(crossings_context, crossings_hit, crossings_near, crossings_far);
      end
      // The medium's end: a scattering inside narrows the closest hit (as a primitive's hit), a shadow ray's optical
      // depth grows; then the scene's leaf goes on.
      if (medium_valid) begin
        medium_out <= medium_out + 1;
        in_medium[medium_context] <= 0;
        optical_depth[medium_context] <= medium_depth;
        primitive_done(medium_context, medium_hit, medium_t, zero, zero);
      end

      // A finished ray leaves, and its context is free.
      hit_valid <= done_valid;
      if (done_valid) begin
        hit_id <= id[done_context];
        hit_found <= found[done_context];
        hit_t <= found_t[done_context];
        hit_b1 <= found_b1[done_context];
        hit_b2 <= found_b2[done_context];
        hit_primitive <= found_primitive[done_context];
        hit_in_mesh <= found_in_mesh[done_context];
        hit_triangle <= found_triangle[done_context];
        hit_optical_depth <= optical_depth[done_context];
        hit_box_tests <= box_tests[done_context];
        hit_primitive_tests <= primitive_tests[done_context];
        state[done_context] <= FREE;
      end
    end
  end
endmodule
`default_nettype wire
