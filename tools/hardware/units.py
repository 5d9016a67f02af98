#!/usr/bin/env python3
# The intersection units (ray-box slab test, ray-triangle, ray-quad, ray-sphere) as dataflow graphs that follow the
# kernel functions of src/kernel/bvh.hpp and src/kernel/shapes.hpp operation for operation, and the command that
# writes one unit in one format as Verilog (and the port list the Verilator testbench binds to).
#
#   units.py --unit triangle --format 16.16 --verilog triangle_q16_16.v [--ports triangle_q16_16_ports.hpp]
#   units.py --unit box --format float32 --verilog box_float32.v     the same unit on IEEE-754 binary32 (float32.py)
#   units.py --list                    the unit names
#   units.py --costs --format 16.16    operation counts and pipeline depth per unit, as CSV
#   units.py --engine-units engine_units_q16_16.v --format 16.16     the traversal engine's units, one file
#
# A unit's inputs are what its kernel function reads, in the order the testbench passes them; its outputs are the
# hit flag and the values the kernel writes. Where the kernel returns early (a miss), the hardware computes
# everything and the flag says whether the values mean anything.

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dataflow import Unit  # noqa: E402
from float32 import FloatUnit  # noqa: E402


def vec_input(u: Unit, name: str):
    return tuple(u.input(f"{name}_{axis}") for axis in "xyz")


def box_unit(u: Unit) -> None:
    """ray_hits_box (src/kernel/bvh.hpp) with ScalarTraits<Fixed>::slab_distance: for each axis the distances to the
    plane met first and the one met last, (bound - origin) * (1 / d) rounded (the traits clamp out-of-range
    distances, as the product's saturation does), then entry = max(max(tx0, ty0), max(tz0, t_min)), exit = min(...),
    hit where entry <= exit. Inputs: the BoxRay's reciprocal direction and origin term (the origin, for fixed point),
    the node's bounds as the BoxRay's plane offsets select them, t_min and t_max.
    In float (ScalarTraits<float>::slab_distance) the distance is bound * (1 / d) - origin * (1 / d), the origin term
    being the product: a multiply, then a subtraction, each rounded (host code is compiled without contraction into
    a fused multiply-add)."""
    inv = vec_input(u, "inv_direction")
    origin = vec_input(u, "origin_term")
    near_bound = vec_input(u, "near_bound")
    far_bound = vec_input(u, "far_bound")
    t_min, t_max = u.input("t_min"), u.input("t_max")
    if u.is_float:
        t0 = [u.sub(u.mul(near_bound[k], inv[k]), origin[k]) for k in range(3)]
        t1 = [u.sub(u.mul(far_bound[k], inv[k]), origin[k]) for k in range(3)]
    else:
        t0 = [u.mul(u.sub(near_bound[k], origin[k]), inv[k]) for k in range(3)]
        t1 = [u.mul(u.sub(far_bound[k], origin[k]), inv[k]) for k in range(3)]
    near = u.max(u.max(t0[0], t0[1]), u.max(t0[2], t_min))
    far = u.min(u.min(t1[0], t1[1]), u.min(t1[2], t_max))
    u.output("hit", u.le(near, far))
    u.output("t_entry", near)


def exact_products(u: Unit) -> bool:
    """Whether the kernel keeps products exact in this format: ScalarTraits<Fixed>::kExactProducts, storage of at most
    32 bits. Float rounds every product (ScalarTraits<float>::kExactProducts is false): the other branch of each
    kernel, which the units below follow for float32 as they do for 64-bit fixed point."""
    return not u.is_float and u.W <= 32


def triangle_unit(u: Unit) -> None:
    """intersect_triangle (Moller-Trumbore, src/kernel/shapes.hpp). With exact products: p = d x e2 and
    q = (o - p0) x e1 exact, det = e1.p, U = (o - p0).p, V = d.q, W = e2.q exact; the inside test on those with the
    sign of det folded in; t, b1, b2 one quotient each by det (the same as by |det| with the signs folded: truncation
    is symmetric). b1 and b2 lie in [0, 1] on a hit, so their dividers make F + 1 quotient bits."""
    p0, edge1, edge2 = vec_input(u, "p0"), vec_input(u, "edge1"), vec_input(u, "edge2")
    origin, direction = vec_input(u, "origin"), vec_input(u, "direction")
    t_min, t_max = u.input("t_min"), u.input("t_max")
    if exact_products(u):
        pvec = u.xcross(direction, edge2)
        det = u.xdot(edge1, pvec)
        tvec = u.vsub(origin, p0)  # rounded (saturating) as Vec3<T> subtraction
        b1 = u.xdot(tvec, pvec)
        qvec = u.xcross(tvec, edge1)
        b2 = u.xdot(direction, qvec)
        t_exact = u.xdot(edge2, qvec)
        zero = u.xzero(det.frac)
        negative = u.xlt(det, zero)
        # The tests on the folded values: U >= 0 is U <= 0 where det < 0, and U + V <= det is U + V >= det.
        b1_inside = u.bit_select(negative, u.xle(b1, zero), u.xge(b1, zero))
        b2_inside = u.bit_select(negative, u.xle(b2, zero), u.xge(b2, zero))
        sum_inside = u.bit_select(negative, u.xge(u.xadd(b1, b2), det), u.xle(u.xadd(b1, b2), det))
        t = u.quotient(t_exact, det)
        hit = u.and_(u.not_(u.xeq(det, zero)), b1_inside, b2_inside, sum_inside, u.gt(t, t_min), u.lt(t, t_max))
        u.output("hit", hit)
        u.output("t", t)
        u.output("b1", u.quotient(b1, det, u.F + 1))
        u.output("b2", u.quotient(b2, det, u.F + 1))
        return
    zero, one = u.zero(), u.one()
    pvec = u.cross(direction, edge2)
    det = u.dot(edge1, pvec)
    inv_det = u.div(one, det)
    tvec = u.vsub(origin, p0)
    b1 = u.mul(u.dot(tvec, pvec), inv_det)
    qvec = u.cross(tvec, edge1)
    b2 = u.mul(u.dot(direction, qvec), inv_det)
    t = u.mul(u.dot(edge2, qvec), inv_det)
    hit = u.and_(u.ne(det, zero), u.ge(b1, zero), u.le(b1, one), u.ge(b2, zero), u.le(u.add(b1, b2), one),
                 u.gt(t, t_min), u.lt(t, t_max))
    u.output("hit", hit)
    u.output("t", t)
    u.output("b1", b1)
    u.output("b2", b2)


def quad_unit(u: Unit) -> None:
    """intersect_quad (src/kernel/shapes.hpp): t from the unit normal, the quad coordinates from the dual edges times
    their extents. With exact products: den = n.d and n.(corner - o) exact, t their quotient; a = du.planar and
    b = dv.planar exact, compared with [0, extent * 2^F]; b1, b2 = a / extent, a shift (extents are powers of two,
    as flatten_scene stores them)."""
    corner, normal = vec_input(u, "corner"), vec_input(u, "normal")
    du, dv = vec_input(u, "du"), vec_input(u, "dv")
    u_extent, v_extent = u.input("u_extent"), u.input("v_extent")
    origin, direction = vec_input(u, "origin"), vec_input(u, "direction")
    t_min, t_max = u.input("t_min"), u.input("t_max")
    one = u.one()
    if exact_products(u):
        denominator = u.xdot(normal, direction)
        zero = u.xzero(denominator.frac)
        t = u.quotient(u.xdot(normal, u.vsub(corner, origin)), denominator)
        planar = u.vsub(u.vadd(origin, u.vscale(direction, t)), corner)
        a, b = u.xdot(du, planar), u.xdot(dv, planar)
        a_max, b_max = u.xmul(u_extent, one), u.xmul(v_extent, one)
        hit = u.and_(u.not_(u.xeq(denominator, zero)), u.gt(t, t_min), u.lt(t, t_max), u.xge(a, zero), u.xle(a, a_max),
                     u.xge(b, zero), u.xle(b, b_max))
        u.output("hit", hit)
        u.output("t", t)
        u.output("b1", u.shift_quotient(a, u_extent))
        u.output("b2", u.shift_quotient(b, v_extent))
        return
    # Formats without exact products store extents of 1: a and b are the dot products themselves.
    zero = u.zero()
    denominator = u.dot(normal, direction)
    t = u.div(u.dot(normal, u.vsub(corner, origin)), denominator)
    at = u.vadd(origin, u.vscale(direction, t))  # ray.at(t) = origin + t * direction
    planar = u.vsub(at, corner)
    a = u.dot(du, planar)
    b = u.dot(dv, planar)
    hit = u.and_(u.ne(denominator, zero), u.gt(t, t_min), u.lt(t, t_max), u.ge(a, zero), u.le(a, one),
                 u.ge(b, zero), u.le(b, one))
    u.output("hit", hit)
    u.output("t", t)
    u.output("b1", a)
    u.output("b2", b)


def sphere_unit(u: Unit) -> None:
    """intersect_sphere with sphere_roots (src/kernel/shapes.hpp): the discriminant from the perpendicular distance to
    the centre, the nearer root if it lies in (t_min, t_max), else the farther. With exact products b is oc.d rounded
    once, and r^2 - |perp|^2 is exact (nothing squared is rounded), its root rounded to nearest."""
    sphere_test(u, vec_input(u, "center"), u.input("radius"))


def sphere_test(u: Unit, center, radius) -> None:
    """The body of sphere_unit for a centre and radius computed or read elsewhere."""
    origin, direction = vec_input(u, "origin"), vec_input(u, "direction")
    t_min, t_max = u.input("t_min"), u.input("t_max")
    misses, near, far = sphere_roots(u, center, radius, origin, direction)
    near_inside = u.and_(u.gt(near, t_min), u.lt(near, t_max))
    far_inside = u.and_(u.gt(far, t_min), u.lt(far, t_max))
    zero = u.zero()
    u.output("hit", u.and_(u.not_(misses), u.or_(near_inside, far_inside)))
    u.output("t", u.select(near_inside, near, far))
    u.output("b1", zero)
    u.output("b2", zero)


def sphere_roots(u: Unit, center, radius, origin, direction):
    """sphere_roots (src/kernel/shapes.hpp): whether the line misses the sphere, and its two crossings."""
    oc = u.vsub(origin, center)
    if exact_products(u):
        b = u.round_exact(u.xdot(oc, direction))
        perpendicular = u.vsub(oc, u.vscale(direction, b))  # oc - b * direction, rounded per operation
        discriminant = u.xsub(u.xmul(radius, radius), u.xdot(perpendicular, perpendicular))
        misses = u.xlt(discriminant, u.xzero(discriminant.frac))
        root = u.exact_sqrt(discriminant)
    else:
        b = u.dot(oc, direction)
        perpendicular = u.vsub(oc, u.vscale(direction, b))
        discriminant = u.sub(u.mul(radius, radius), u.dot(perpendicular, perpendicular))
        misses = u.lt(discriminant, u.zero())
        root = u.sqrt(discriminant)
    minus_b = u.neg(b)
    return misses, u.sub(minus_b, root), u.add(minus_b, root)


def sphere_crossings_unit(u: Unit) -> None:
    """The crossings of a medium's spherical boundary with the ray's whole line (widen_to_crossings,
    src/kernel/shapes.hpp): sphere_roots' near and far, and whether the line meets the sphere at all."""
    origin, direction = vec_input(u, "origin"), vec_input(u, "direction")
    misses, near, far = sphere_roots(u, vec_input(u, "center"), u.input("radius"), origin, direction)
    u.output("hit", u.not_(misses))
    u.output("near", near)
    u.output("far", far)


def medium_unit(u: Unit) -> None:
    """The end of intersect_medium (src/kernel/shapes.hpp), once the boundary's crossings are known (first, last):
    the line's stretch inside, clipped to (0, t_max); for a shadow ray (`shadow` not 0) the optical depth it adds,
    (entry - exit) / neg_inv_density, summed into optical_depth; for another the free-flight distance `distance`
    (neg_inv_density log(1 - u), drawn beside the ray) compared with the stretch, and the hit at entry + distance."""
    first, last, t_max = u.input("first"), u.input("last"), u.input("t_max")
    distance, neg_inv_density = u.input("distance"), u.input("neg_inv_density")
    optical_depth, shadow = u.input("optical_depth"), u.input("shadow")
    zero = u.zero()
    entry = u.max(u.max(first, zero), zero)  # max(entry, t_min), then max(entry, 0)
    exit_ = u.min(last, t_max)
    inside = u.lt(entry, exit_)
    is_shadow = u.ne(shadow, zero)
    u.output("hit", u.and_(u.not_(is_shadow), inside, u.not_(u.gt(distance, u.sub(exit_, entry)))))
    u.output("t", u.add(entry, distance))
    u.output("optical_depth_out", u.select(u.and_(is_shadow, inside), u.add(optical_depth, u.div(u.sub(entry, exit_), neg_inv_density)),
                                       optical_depth))


def moving_sphere_unit(u: Unit) -> None:
    """intersect_sphere at moving_sphere_center(s, time) = center0 + (time - time0) * velocity (src/kernel/shapes.hpp),
    the sphere test above after it. A sphere that does not move is this unit's with velocity 0 and time0 0: the
    product is then 0 and the sum center0, exactly, so the traversal engine has one unit for both kinds."""
    center0, radius = vec_input(u, "center0"), u.input("radius")
    velocity, time0, time = vec_input(u, "velocity"), u.input("time0"), u.input("ray_time")  # `time` is a Verilog word
    center = u.vadd(center0, u.vscale(velocity, u.sub(time, time0)))
    sphere_test(u, center, radius)


def instance_ray_unit(u: Unit) -> None:
    """instance_ray (src/kernel/bvh.hpp): a world ray taken into a mesh instance's space by AffineRows::point and
    ::vector (src/kernel/shapes.hpp), each component a dot product of a row with the vector, the translation added to
    the origin's. An instance without a transform is this unit's with the identity: 1 * x rounds to x and 0 * y is 0,
    exactly, so the traversal engine sends every instance through it."""
    rows = [vec_input(u, f"row{k}") for k in range(3)]
    translation = vec_input(u, "translation")
    origin, direction = vec_input(u, "origin"), vec_input(u, "direction")
    moved_origin = u.vadd(tuple(u.dot(row, origin) for row in rows), translation)
    moved_direction = tuple(u.dot(row, direction) for row in rows)
    for axis, o, d in zip("xyz", moved_origin, moved_direction):
        u.output(f"local_origin_{axis}", o)
        u.output(f"local_direction_{axis}", d)


def ray_setup_unit(u: Unit) -> None:
    """slab_reciprocals (src/kernel/bvh.hpp) with ScalarTraits<Fixed>::slab_reciprocal: 1 / d per axis, truncated,
    the largest value where d is 0, which is Fixed's operator/ on 1 and d. The traversal engine's ray entry."""
    direction = vec_input(u, "direction")
    one = u.one()
    for axis, d in zip("xyz", direction):
        u.output(f"inv_{axis}", u.div(one, d))


UNITS = {"box": box_unit, "triangle": triangle_unit, "quad": quad_unit, "sphere": sphere_unit,
         "moving_sphere": moving_sphere_unit, "ray_setup": ray_setup_unit, "instance_ray": instance_ray_unit,
         "sphere_crossings": sphere_crossings_unit, "medium": medium_unit}


def build(name: str, integer_bits: int, fraction_bits: int, **options) -> Unit:
    """The unit in Q(integer_bits).(fraction_bits), or in float32 where both are 0 (parse_format("float32"))."""
    u = FloatUnit(name, **options) if integer_bits == 0 and fraction_bits == 0 else Unit(name, integer_bits, fraction_bits, **options)
    UNITS[name](u)
    return u


def ports_header(u: Unit, model_class: str = "") -> str:
    """The unit's ports for the C++ testbench: the inputs in order and a function that sets them from raw values.
    model_class: the Verilated model's class (Verilator's --prefix), V<module> by default."""
    cls = model_class or f"V{u.module_name}"
    lines = [f"// Ports of {u.module_name} (generated by tools/hardware/units.py; do not edit).",
             "#pragma once",
             f'#include "{cls}.h"',
             "",
             f"namespace {cls}_binding {{  // each unit's binding apart: several testbenches may share a source",
             "struct UnitPorts {",
             f"  using Model = {cls};",
             f"  static constexpr int kIntegerBits = {u.I}, kFractionBits = {u.F}, kLatency = {u.latency()};",
             f"  static constexpr const char* kInputs[] = {{{', '.join(f'{chr(34)}{n}{chr(34)}' for n, _ in u.inputs)}}};",
             f"  static constexpr const char* kOutputs[] = {{{', '.join(f'{chr(34)}{n}{chr(34)}' for n, _ in u.outputs)}}};",
             "  // Raw values in two's complement, W bits each; the model wants the bits above W clear.",
             "  template <class Raw>",
             "  static void set_inputs(Model& m, const Raw* in) {",
             f"    constexpr unsigned long long mask = {hex((1 << u.W) - 1)}ULL;"]
    for k, (name, _) in enumerate(u.inputs):
        lines.append(f"    m.{name} = static_cast<unsigned long long>(static_cast<long long>(in[{k}])) & mask;")
    lines += ["  }",
              "  // Outputs sign-extended from W bits (the hit flag as 0 or 1).",
              "  static void get_outputs(const Model& m, long long* out) {"]
    for k, (name, v) in enumerate(u.outputs):
        if v.is_bit:
            lines.append(f"    out[{k}] = m.{name};")
        else:
            lines.append(f"    out[{k}] = static_cast<long long>(static_cast<unsigned long long>(m.{name}) << {64 - u.W}) >> {64 - u.W};")
    lines += ["  }", "};", f"}}  // namespace {cls}_binding", ""]
    return "\n".join(lines)


# The units the traversal engine (src/backends/rtl/traversal_engine.v) instantiates, by the macro it names each with.
ENGINE_UNITS = {"PT_RAY_SETUP_UNIT": "ray_setup", "PT_BOX_UNIT": "box", "PT_SPHERE_UNIT": "moving_sphere",
                "PT_TRIANGLE_UNIT": "triangle", "PT_QUAD_UNIT": "quad", "PT_INSTANCE_RAY_UNIT": "instance_ray",
                "PT_CROSSINGS_UNIT": "sphere_crossings", "PT_MEDIUM_UNIT": "medium"}


def engine_units(integer_bits: int, fraction_bits: int, **options) -> str:
    """The engine's units in one format as one Verilog file: a `define naming each unit's module for the engine, then
    the units, each shared submodule once."""
    lines = [f"// The traversal engine's units in Q{integer_bits}.{fraction_bits} (generated by tools/hardware/units.py "
             "--engine-units; do not edit)."]
    mains, shared = [], {}
    for macro, name in ENGINE_UNITS.items():
        u = build(name, integer_bits, fraction_bits, **options)
        lines.append(f"`define {macro} {u.module_name}")
        main, modules = u.verilog_parts()
        mains.append(main)
        for module_name, text in modules.items():
            shared.setdefault(module_name, text)
    lines.append(f"`define PT_ENGINE_WORD {integer_bits + fraction_bits}")
    return "\n".join(lines) + "\n" + "".join(mains) + "".join(shared.values())


def format_label(u: Unit) -> str:
    """The format as synthesis.csv and the tests name it: q16.16, float32."""
    return "float32" if u.is_float else f"q{u.I}.{u.F}"


def parse_format(text: str):
    """(integer bits, fraction bits) of "16.16" or "q16.16"; (0, 0) for "float32"."""
    if text == "float32":
        return 0, 0
    integer, fraction = text.lstrip("q").split(".")
    return int(integer), int(fraction)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--unit", choices=sorted(UNITS))
    parser.add_argument("--format", help="INTEGER.FRACTION bits, e.g. 16.16 (the sign bit counts as an integer bit), or float32")
    parser.add_argument("--verilog", help="write the unit's Verilog here")
    parser.add_argument("--ports", help="write the C++ port binding for the Verilator testbench here")
    parser.add_argument("--model-class", default="", help="the Verilated model's class name (Verilator's --prefix)")
    parser.add_argument("--divide-steps", type=int, default=1, help="quotient bits per pipeline stage")
    parser.add_argument("--root-steps", type=int, default=1, help="root digits per pipeline stage")
    parser.add_argument("--fault", default="", help="build a deliberately wrong unit: truncate-products")
    parser.add_argument("--engine-units", help="write the traversal engine's units in --format here, as one file")
    parser.add_argument("--list", action="store_true")
    parser.add_argument("--costs", action="store_true")
    args = parser.parse_args()
    if args.list:
        print("\n".join(sorted(UNITS)))
        return 0
    integer_bits, fraction_bits = parse_format(args.format)
    options = dict(divide_steps_per_stage=args.divide_steps, root_steps_per_stage=args.root_steps, fault=args.fault)
    if args.engine_units:
        Path(args.engine_units).write_text(engine_units(integer_bits, fraction_bits, **options))
        return 0
    if args.costs:
        print("unit,format,adds,multiplies,divides,square_roots,compares,exact_multiplies,exact_adds,latency")
        for name in sorted(UNITS):
            u = build(name, integer_bits, fraction_bits, **options)
            c = u.costs()
            print(f"{name},{format_label(u)},{c.add},{c.mul},{c.div},{c.sqrt},{c.compare},{c.exact_mul},{c.exact_add},{u.latency()}")
        return 0
    u = build(args.unit, integer_bits, fraction_bits, **options)
    if args.verilog:
        Path(args.verilog).write_text(u.verilog())
    if args.ports:
        Path(args.ports).write_text(ports_header(u, args.model_class))
    return 0


if __name__ == "__main__":
    sys.exit(main())
