#!/usr/bin/env python3
# The hardware units (ray-box slab test, ray-triangle, ray-quad, ray-sphere and the traversal engine's others) made
# from the kernel source: tools/hardware/record_graphs.cpp runs each unit's model (tools/hardware/operands.hpp, which
# calls the kernel function) on a scalar type that records every operation, and this writes the recorded dataflow in
# one format as pipelined Verilog (dataflow.py, float32.py), with the port list the Verilator testbench binds to. A
# change to a kernel formula changes the hardware; the testbench checks every unit bit for bit against the kernel.
#
#   units.py --unit triangle --format 16.16 --verilog triangle_q16_16.v [--ports triangle_q16_16_ports.hpp]
#   units.py --unit box --format float32 --verilog box_float32.v     the same unit on IEEE-754 binary32 (float32.py)
#   units.py --list                    the unit names
#   units.py --costs --format 16.16    operation counts and pipeline depth per unit, as CSV
#   units.py --engine-units engine_units_q16_16.v --format 16.16     the traversal engine's units, one file
#   units.py --record-graphs graphs.json [--cxx g++]     record the graphs once; --graphs graphs.json reads them
#
# Without --graphs (or $PT_UNIT_GRAPHS) the graphs are recorded on each run (a C++ compile of a second or two).
# A unit's inputs are what its kernel function reads, in the order the testbench passes them; its outputs are the
# hit flag and the values the kernel writes. Where the kernel returns early (a miss), the hardware computes
# everything and the flag says whether the values mean anything.

import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from dataflow import Unit  # noqa: E402
from float32 import FloatUnit  # noqa: E402


# The units, each the model of its operand set in tools/hardware/operands.hpp, which calls the kernel function named.
UNITS = {
    "box": "ray_hits_box (src/kernel/bvh.hpp): the slab test of a node's box, with the BoxRay's planes chosen",
    "triangle": "intersect_triangle (src/kernel/shapes.hpp): Moller-Trumbore",
    "quad": "intersect_quad (src/kernel/shapes.hpp)",
    "sphere": "intersect_sphere with sphere_roots (src/kernel/shapes.hpp)",
    "moving_sphere": "intersect_sphere at moving_sphere_center (src/kernel/shapes.hpp); a standing sphere has velocity 0",
    "ray_setup": "slab_reciprocals (src/kernel/bvh.hpp): 1 / d per axis, the traversal engine's ray entry",
    "instance_ray": "instance_ray (src/kernel/bvh.hpp): a world ray taken into a mesh instance's space",
    "sphere_crossings": "sphere_roots (src/kernel/shapes.hpp): where a line crosses a medium's spherical boundary",
    "medium": "medium_event (src/kernel/shapes.hpp): a medium's stretch of the ray, free flight or optical depth",
}
FLOAT32_UNITS = ("box", "triangle", "quad", "sphere")  # the others take part in fixed-point engines only

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
_graphs: dict | None = None


def record_graphs(cxx: str = "", sources: Path = ROOT / "src") -> dict:
    """Compiles tools/hardware/record_graphs.cpp (the kernel's unit models on a recording scalar type) against the
    kernel headers under `sources` and runs it: the units' dataflow graphs, for each kind of scalar."""
    compiler = cxx or os.environ.get("CXX") or "c++"
    with tempfile.TemporaryDirectory() as work:
        program = Path(work) / "record_graphs"
        subprocess.run([compiler, "-std=c++20", "-O1", f"-I{sources}", f"-I{ROOT / 'tools'}", str(HERE / "record_graphs.cpp"),
                        "-o", str(program)], check=True)
        text = subprocess.run([str(program)], check=True, capture_output=True, text=True).stdout
    return json.loads(text)


def graphs(path: str = "") -> dict:
    """The recorded graphs: from `path` (or $PT_UNIT_GRAPHS) where given, else recorded now, once per process."""
    global _graphs
    if _graphs is None:
        source = path or os.environ.get("PT_UNIT_GRAPHS", "")
        _graphs = json.loads(Path(source).read_text()) if source else record_graphs()
    return _graphs


class _Expr:
    """A node of the joined datapath: a recorded operation, or a multiplexer or bit logic made when joining paths.
    Hash-consed (make), so that equal expressions are one node."""
    __slots__ = ("op", "args", "value", "name")

    def __init__(self, op, args, value, name):
        self.op, self.args, self.value, self.name = op, args, value, name


class _Joiner:
    """Joins the paths of one recorded unit into one datapath. The decisions of all paths form a binary tree (every
    way of every decision was followed); each output is a multiplexer tree over the decisions' bits, with the values
    of the paths at its leaves; an output that means something only on a hit takes no leaf from a path that missed,
    and the hit flag has the returned constants at its leaves. Multiplexers are pushed below operations of the same
    kind (select(c, q(a, b), q(a', b')) = q(select(c, a, a'), select(c, b, b'))), so that the ways of a branch share
    one divider, one root, one compare, as a hand-written datapath would."""

    DONT_CARE = _Expr("dont_care", (), 0, "")

    def __init__(self, graph: dict):
        self.table: dict = {}
        self.kept: set[int] = set()  # nodes the datapath has anyway: a multiplexer of two of them is not pushed down
        self.recorded: list[_Expr] = []
        for op, args, value, name in graph["nodes"]:
            self.recorded.append(self.make(op, tuple(self.recorded[a] for a in args), value, name))
        self.one_bit = self.make("bit", (), 1)
        self.zero_bit = self.make("bit", (), 0)

    def make(self, op, args=(), value=0, name="") -> _Expr:
        key = (op, tuple(id(a) for a in args), value, name)
        node = self.table.get(key)
        if node is None:
            node = self.table[key] = _Expr(op, args, value, name)
        return node

    def select(self, c: _Expr, a: _Expr, b: _Expr) -> _Expr:
        if a is self.DONT_CARE or a is b:
            return b
        if b is self.DONT_CARE:
            return a
        if c.op == "not":
            return self.select(c.args[0], b, a)
        if a.op == "bit" and b.op == "bit":
            return c if a.value else self.make("not", (c,))
        if a.op == "bit":
            return self.make("or", (c, b)) if a.value else self.make("and", (self.make("not", (c,)), b))
        if b.op == "bit":
            return self.make("or", (self.make("not", (c,)), a)) if b.value else self.make("and", (c, a))
        both_kept = id(a) in self.kept and id(b) in self.kept
        if a.op == b.op and len(a.args) == len(b.args) and a.args and a.value == b.value and not both_kept:
            return self.make(a.op, tuple(self.select(c, x, y) for x, y in zip(a.args, b.args)), a.value)
        return self.make("select", (c, a, b))

    def join_all(self, graph: dict):
        """(hit, outputs) of the unit. Pushing a multiplexer below an operation saves that operation only where neither
        way's is needed elsewhere: the decisions' bits that the joined datapath keeps (the hit flag's logic and every
        multiplexer's select) need the values they compare. So the paths are joined twice: first pushing everywhere,
        to find those bits; then keeping what they reach, so that, say, the sphere's distance is a multiplexer of the
        two crossings its range tests need anyway rather than a third divider."""
        only_on_hit = [only for _, only in graph["outputs"]]
        hit, outputs = self.join(graph["paths"], 0, only_on_hit)
        roots, seen, stack = [hit], set(), list(outputs)
        while stack:
            e = stack.pop()
            if id(e) in seen:
                continue
            seen.add(id(e))
            if e.op == "select":
                roots.append(e.args[0])
            stack.extend(e.args)
        stack = roots
        while stack:
            e = stack.pop()
            if id(e) not in self.kept:
                self.kept.add(id(e))
                stack.extend(e.args)
        return self.join(graph["paths"], 0, only_on_hit)

    def join(self, paths: list, depth: int, only_on_hit: list[bool]):
        """(hit, outputs) of the paths that share their first `depth` decisions."""
        if len(paths) == 1 and len(paths[0]["decisions"]) == depth:
            path = paths[0]
            returned = bool(path["returned"])
            outputs = [self.recorded[o] if returned or not only else self.DONT_CARE for o, only in zip(path["outputs"], only_on_hit)]
            return (self.one_bit if returned else self.zero_bit), outputs
        bit = self.recorded[paths[0]["decisions"][depth][0]]
        ways = [[p for p in paths if p["decisions"][depth][1] == way] for way in (1, 0)]
        assert all(ways) and all(p["decisions"][depth][0] == paths[0]["decisions"][depth][0] for p in paths)
        (hit_true, out_true), (hit_false, out_false) = (self.join(w, depth + 1, only_on_hit) for w in ways)
        return self.select(bit, hit_true, hit_false), [self.select(bit, a, b) for a, b in zip(out_true, out_false)]


def _fixed_constant(u: Unit, value: float) -> int:
    """The raw value of Fixed(value): rounded half away from zero, saturated (kernel/fixed_point.hpp)."""
    scaled = value * (1 << u.F)
    if scaled >= u.max_raw:
        return u.max_raw
    if scaled <= -u.max_raw:
        return -u.max_raw
    return int(scaled + (0.5 if scaled >= 0 else -0.5))


class _Builder:
    """Builds a Unit from the joined datapath: each node as the dataflow.py operation of the same semantics."""

    SIMPLE = {"add", "sub", "mul", "div", "neg", "min", "max", "sqrt", "lt", "le", "eq"}

    def __init__(self, u: Unit, joiner: _Joiner, graph: dict):
        self.u = u
        self.values: dict[int, object] = {}
        for name, node in graph["inputs"]:  # every port, in the operand set's order, used or not
            self.values[id(joiner.recorded[node])] = u.input(name)

    def value(self, e: _Expr):
        v = self.values.get(id(e))
        if v is None:
            v = self.values[id(e)] = self.make(e)
        return v

    def exact_zero_or(self, e: _Expr, other):
        return self.u.xzero(other.frac) if e.op == "xzero" else self.value(e)

    def make(self, e: _Expr):
        u, op = self.u, e.op
        if op == "const":
            return u.const(struct.unpack("<I", struct.pack("<f", e.value))[0] if u.is_float else _fixed_constant(u, e.value))
        if op == "largest":
            return u.const(0x7F7FFFFF if u.is_float else u.max_raw)
        if op in ("xlt", "xle", "xeq"):
            a = e.args[0] if e.args[0].op != "xzero" else e.args[1]
            known = self.value(a)
            x, y = (self.exact_zero_or(arg, known) for arg in e.args)
            return {"xlt": u.xlt, "xle": u.xle, "xeq": u.xeq}[op](x, y)
        args = [self.value(a) for a in e.args]
        if op in self.SIMPLE:
            return getattr(u, op)(*args)
        if op in ("and", "or"):
            return getattr(u, op + "_")(*args)
        if op == "not":
            return u.not_(args[0])
        if op == "select":
            c, a, b = args
            if a.is_bit:
                return u.bit_select(c, a, b)
            return u.select(c, a, b) if a.width == u.W and b.width == u.W else u.xselect(c, a, b)
        if op in ("xmul", "xadd", "xsub"):
            return getattr(u, op)(*args)
        if op == "xneg":
            return u.xsub(u.xzero(args[0].frac), args[0])
        if op == "round":
            return u.round_exact(args[0])
        if op == "xsqrt":
            return u.exact_sqrt(args[0])
        if op == "xroot":
            return u.exact_root(args[0])
        if op == "quotient":
            return u.quotient(*args)
        if op == "fraction":  # a quotient in [0, 1] wherever it is used: F + 1 quotient bits
            return u.quotient(*args, u.F + 1)
        if op == "shift_quotient":
            return u.shift_quotient(*args)
        raise ValueError(f"{u.name}: the kernel's dataflow has an operation '{op}' that no hardware operator implements")


def build_from_graph(u: Unit, graph: dict) -> Unit:
    """The unit `u` (empty, in its format) made from its recorded graph."""
    joiner = _Joiner(graph)
    hit, outputs = joiner.join_all(graph)
    builder = _Builder(u, joiner, graph)
    if graph["has_hit"]:
        u.output("hit", builder.value(hit))
    for (name, _), e in zip(graph["outputs"], outputs):
        u.output(name, builder.value(e))
    return u


def build(name: str, integer_bits: int, fraction_bits: int, graphs_file: str = "", recorded: dict | None = None, **options) -> Unit:
    """The unit in Q(integer_bits).(fraction_bits), or in float32 where both are 0 (parse_format("float32")), from the
    kernel's recorded dataflow (exact products in fixed point of up to 32 bits, as the kernel keeps them)."""
    if integer_bits == 0 and fraction_bits == 0:
        if name not in FLOAT32_UNITS:
            raise ValueError(f"the {name} unit is made in fixed point only")
        u, kind = FloatUnit(name, **options), "float"
    else:
        u = Unit(name, integer_bits, fraction_bits, **options)
        kind = "exact_fixed" if u.W <= 32 else "rounded_fixed"
    return build_from_graph(u, (recorded or graphs(graphs_file))[kind][name])


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
    parser.add_argument("--graphs", default="", help="the units' graphs as --record-graphs wrote them (else recorded now)")
    parser.add_argument("--record-graphs", help="record the units' graphs from the kernel source into this file, and stop")
    parser.add_argument("--cxx", default="", help="the C++ compiler to record with (default: $CXX, else c++)")
    parser.add_argument("--list", action="store_true")
    parser.add_argument("--costs", action="store_true")
    args = parser.parse_args()
    if args.list:
        print("\n".join(sorted(UNITS)))
        return 0
    if args.record_graphs:
        Path(args.record_graphs).write_text(json.dumps(record_graphs(args.cxx)))
        return 0
    graphs(args.graphs)
    integer_bits, fraction_bits = parse_format(args.format)
    options = dict(divide_steps_per_stage=args.divide_steps, root_steps_per_stage=args.root_steps, fault=args.fault)
    if args.engine_units:
        Path(args.engine_units).write_text(engine_units(integer_bits, fraction_bits, **options))
        return 0
    if args.costs:
        print("unit,format,adds,multiplies,divides,square_roots,compares,exact_multiplies,exact_adds,latency")
        for name in sorted(UNITS if (integer_bits, fraction_bits) != (0, 0) else FLOAT32_UNITS):
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
