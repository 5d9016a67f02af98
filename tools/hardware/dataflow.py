# Dataflow graphs of fixed-point operations with the semantics of the C++ Fixed<I, F> (src/kernel/fixed_point.hpp),
# scheduled into a pipeline and written out as synthesisable Verilog-2005.
#
# Each operation is the hardware image of one C++ operator on Fixed<I, F>:
#   add, sub   the sum or difference formed one bit wider, then saturated to +-(2^(W-1) - 1)
#   mul        the full product, plus half a step, shifted right by F (rounds half up, as the C++ shift does),
#              then saturated
#   div        (a << F) / b truncated toward zero and saturated; b == 0 gives +-max with the sign of a
#   sqrt       the integer square root of (x << F), digit by digit, rounded to nearest; x <= 0 gives 0
#   neg        two's complement negation (the range is symmetric, so it never overflows)
#   min, max   a < b ? a : b and a > b ? a : b
#   lt .. ne   signed compares, giving one bit; and_, or_, not_ combine bits
#   select     c ? a : b
# Values are signed W = I + F bit integers (the raw field of Fixed). Every operation but the bit logic ends in a
# register, so that a new operand set can enter every clock; the scheduler places each operation as early as its
# operands allow and delays values through register chains to the stage where they are used.

from __future__ import annotations

from dataclasses import dataclass, field


def literal(value: int, width: int) -> str:
    """A sized signed Verilog literal."""
    return f"{width}'sd{value}" if value >= 0 else f"-{width}'sd{-value}"


@dataclass
class Value:
    unit: "Unit"
    index: int
    op: str
    args: tuple
    width: int  # W for fixed-point values, 1 for bits
    latency: int
    param: int = 0  # the raw value of a constant
    ready: int = 0  # the stage from which the value is valid
    start: int = 0  # the stage in which its operation reads its operands
    name: str = ""

    @property
    def is_bit(self) -> bool:
        return self.width == 1


@dataclass
class Costs:
    """Operation counts of a unit (for comparison with floating point, whose cost is quoted per operator)."""
    add: int = 0
    mul: int = 0
    div: int = 0
    sqrt: int = 0
    compare: int = 0


class Unit:
    """A pipelined unit: inputs, operations, outputs. Options: steps of a divider or square root per stage, and a
    deliberate fault (products truncated instead of rounded) to show that the testbench finds a wrong unit."""

    def __init__(self, name: str, integer_bits: int, fraction_bits: int, divide_steps_per_stage: int = 1,
                 root_steps_per_stage: int = 1, fault: str = ""):
        if integer_bits < 2 or fraction_bits < 1:
            raise ValueError("formats need at least 2 integer bits (the sign and one) and 1 fraction bit")
        self.name = name
        self.I = integer_bits
        self.F = fraction_bits
        self.W = integer_bits + fraction_bits
        self.max_raw = (1 << (self.W - 1)) - 1
        self.divide_steps = divide_steps_per_stage
        self.root_steps = root_steps_per_stage
        if fault not in ("", "truncate-products"):
            raise ValueError(f"unknown fault {fault!r}")
        self.fault = fault
        self.values: list[Value] = []
        self.inputs: list[tuple[str, Value]] = []
        self.outputs: list[tuple[str, Value]] = []

    # ---- latencies, shared with the submodules below ----
    def divide_latency(self) -> int:
        return 2 + -(-(self.W - 1) // self.divide_steps)

    def root_digits(self) -> int:
        return (self.W - 1 + self.F + 1) // 2

    def root_latency(self) -> int:
        return 2 + -(-self.root_digits() // self.root_steps)

    @property
    def module_name(self) -> str:
        return f"{self.name}_unit_q{self.I}_{self.F}"

    # ---- building the graph ----
    def _value(self, op: str, args: tuple, width: int, latency: int, param: int = 0) -> Value:
        for a in args:
            assert a.unit is self
        v = Value(self, len(self.values), op, args, width, latency, param)
        v.start = max((a.ready for a in args), default=0)
        v.ready = v.start + latency
        v.name = f"v{v.index}_{op}"
        self.values.append(v)
        return v

    def input(self, name: str) -> Value:
        v = self._value("input", (), self.W, 0)
        v.name = name
        self.inputs.append((name, v))
        return v

    def output(self, name: str, value: Value) -> None:
        self.outputs.append((name, value))

    def const(self, raw: int) -> Value:
        assert -self.max_raw <= raw <= self.max_raw
        return self._value("const", (), self.W, 0, raw)

    def one(self) -> Value:
        return self.const(1 << self.F)

    def zero(self) -> Value:
        return self.const(0)

    def _fixed(self, *args: Value) -> None:
        assert all(not a.is_bit for a in args), "a fixed-point operation was given a bit"

    def add(self, a, b): self._fixed(a, b); return self._value("add", (a, b), self.W, 1)
    def sub(self, a, b): self._fixed(a, b); return self._value("sub", (a, b), self.W, 1)
    def mul(self, a, b): self._fixed(a, b); return self._value("mul", (a, b), self.W, 2)
    def div(self, a, b): self._fixed(a, b); return self._value("div", (a, b), self.W, self.divide_latency())
    def sqrt(self, a): self._fixed(a); return self._value("sqrt", (a,), self.W, self.root_latency())
    def neg(self, a): self._fixed(a); return self._value("neg", (a,), self.W, 1)
    def min(self, a, b): self._fixed(a, b); return self._value("min", (a, b), self.W, 1)
    def max(self, a, b): self._fixed(a, b); return self._value("max", (a, b), self.W, 1)
    def lt(self, a, b): self._fixed(a, b); return self._value("lt", (a, b), 1, 1)
    def le(self, a, b): self._fixed(a, b); return self._value("le", (a, b), 1, 1)
    def gt(self, a, b): return self.lt(b, a)
    def ge(self, a, b): return self.le(b, a)
    def eq(self, a, b): self._fixed(a, b); return self._value("eq", (a, b), 1, 1)
    def ne(self, a, b): return self.not_(self.eq(a, b))
    def and_(self, *bits): return self._reduce("and", bits)
    def or_(self, *bits): return self._reduce("or", bits)
    def not_(self, a): assert a.is_bit; return self._value("not", (a,), 1, 0)

    def _reduce(self, op: str, bits) -> Value:
        assert all(b.is_bit for b in bits)
        return self._value(op, tuple(bits), 1, 0)

    def select(self, c, a, b):
        assert c.is_bit
        self._fixed(a, b)
        return self._value("select", (c, a, b), self.W, 1)

    # Vector helpers with the kernel's order of operations (src/kernel/vec3.hpp).
    def vsub(self, a, b): return tuple(self.sub(x, y) for x, y in zip(a, b))
    def vadd(self, a, b): return tuple(self.add(x, y) for x, y in zip(a, b))
    def vscale(self, v, s): return tuple(self.mul(x, s) for x in v)  # {a.x * s, a.y * s, a.z * s}

    def dot(self, a, b):
        """x*x' + y*y' + z*z', summed left to right, each operation saturating."""
        return self.add(self.add(self.mul(a[0], b[0]), self.mul(a[1], b[1])), self.mul(a[2], b[2]))

    def cross(self, a, b):
        return (self.sub(self.mul(a[1], b[2]), self.mul(a[2], b[1])),
                self.sub(self.mul(a[2], b[0]), self.mul(a[0], b[2])),
                self.sub(self.mul(a[0], b[1]), self.mul(a[1], b[0])))

    def costs(self) -> Costs:
        c = Costs()
        for v in self.values:
            if v.op in ("add", "sub"): c.add += 1
            elif v.op == "mul": c.mul += 1
            elif v.op == "div": c.div += 1
            elif v.op == "sqrt": c.sqrt += 1
            elif v.op in ("lt", "le", "eq", "min", "max"): c.compare += 1
        return c

    def latency(self) -> int:
        return max(v.ready for _, v in self.outputs)

    # ---- Verilog ----
    def verilog(self) -> str:
        return Emitter(self).emit()


class Emitter:
    def __init__(self, unit: Unit):
        self.u = unit
        self.delays: dict[int, int] = {}  # value index -> longest delay chain needed
        self.body: list[str] = []
        self.decls: list[str] = []

    def ref(self, v: Value, stage: int) -> str:
        """The name under which v is valid at `stage`."""
        if v.op == "const":
            return f"({literal(v.param, self.u.W)})"
        k = stage - v.ready
        assert k >= 0, f"{v.name} read at stage {stage} before it is ready ({v.ready})"
        if k == 0:
            return v.name
        self.delays[v.index] = max(self.delays.get(v.index, 0), k)
        return f"{v.name}_d{k}"

    def saturate(self, expr: str, width: int) -> str:
        u = self.u
        return (f"(({expr}) > {literal(u.max_raw, width)}) ? {literal(u.max_raw, u.W)} : "
                f"(({expr}) < {literal(-u.max_raw, width)}) ? {literal(-u.max_raw, u.W)} : {expr}[{u.W - 1}:0]")

    def emit_value(self, v: Value) -> None:
        u, W, F = self.u, self.u.W, self.u.F
        a = [self.ref(x, v.start) for x in v.args]
        decl = "reg" if v.latency > 0 else "wire"
        sign = "" if v.is_bit else "signed "
        rng = "" if v.is_bit else f"[{W - 1}:0] "
        n = v.name
        if v.op in ("input", "const"):
            return
        self.decls.append(f"  {decl} {sign}{rng}{n};")
        if v.op in ("add", "sub"):
            op = "+" if v.op == "add" else "-"
            self.decls.append(f"  wire signed [{W}:0] {n}_wide = {a[0]} {op} {a[1]};")
            self.body.append(f"    {n} <= {self.saturate(n + '_wide', W + 1)};")
        elif v.op == "mul":
            half = 0 if u.fault == "truncate-products" else 1 << (F - 1)
            self.decls.append(f"  reg signed [{2 * W - 1}:0] {n}_product;")
            self.decls.append(f"  wire signed [{2 * W - 1}:0] {n}_rounded = {n}_product + {literal(half, 2 * W)};")
            self.decls.append(f"  wire signed [{2 * W - F - 1}:0] {n}_shifted = {n}_rounded[{2 * W - 1}:{F}];")
            self.body.append(f"    {n}_product <= {a[0]} * {a[1]};")
            self.body.append(f"    {n} <= {self.saturate(n + '_shifted', 2 * W - F)};")
        elif v.op == "div":
            self.decls.append(f"  fixed_divide_q{u.I}_{u.F} {n}_divider(.clk(clk), .a({a[0]}), .b({a[1]}), .quotient({n}));")
            self.decls[-2] = f"  wire signed [{W - 1}:0] {n};"
        elif v.op == "sqrt":
            self.decls.append(f"  fixed_sqrt_q{u.I}_{u.F} {n}_root(.clk(clk), .x({a[0]}), .root({n}));")
            self.decls[-2] = f"  wire signed [{W - 1}:0] {n};"
        elif v.op == "neg":
            self.body.append(f"    {n} <= -{a[0]};")
        elif v.op in ("min", "max"):
            cmp = "<" if v.op == "min" else ">"
            self.body.append(f"    {n} <= ({a[0]} {cmp} {a[1]}) ? {a[0]} : {a[1]};")
        elif v.op in ("lt", "le", "eq"):
            cmp = {"lt": "<", "le": "<=", "eq": "=="}[v.op]
            self.body.append(f"    {n} <= ({a[0]} {cmp} {a[1]});")
        elif v.op in ("and", "or"):
            self.decls[-1] = f"  wire {n} = {(' & ' if v.op == 'and' else ' | ').join(a)};"
        elif v.op == "not":
            self.decls[-1] = f"  wire {n} = ~{a[0]};"
        elif v.op == "select":
            self.body.append(f"    {n} <= {a[0]} ? {a[1]} : {a[2]};")
        else:
            raise AssertionError(v.op)

    def emit(self) -> str:
        u = self.u
        W = u.W
        latency = u.latency()
        for v in u.values:
            self.emit_value(v)
        outputs = [(name, self.ref(v, latency), v) for name, v in u.outputs]
        # Delay chains, now that every reader is known.
        chains = []
        for index, depth in sorted(self.delays.items()):
            v = u.values[index]
            sign = "" if v.is_bit else "signed "
            rng = "" if v.is_bit else f"[{W - 1}:0] "
            for k in range(1, depth + 1):
                self.decls.append(f"  reg {sign}{rng}{v.name}_d{k};")
                chains.append(f"    {v.name}_d{k} <= {v.name if k == 1 else f'{v.name}_d{k - 1}'};")
        ports = ["  input wire clk", "  input wire in_valid"]
        ports += [f"  input wire signed [{W - 1}:0] {name}" for name, _ in u.inputs]
        ports.append("  output wire out_valid")
        for name, _, v in outputs:
            ports.append(f"  output wire {'' if v.is_bit else f'signed [{W - 1}:0] '}{name}")
        lines = [
            f"// {u.name} unit in Q{u.I}.{u.F} (generated by tools/hardware/units.py; do not edit): one operand set per clock,",
            f"// results {latency} clocks later. Bit-exact with the kernel function on Fixed<{u.I}, {u.F}>.",
            f"module {u.module_name} (",
            ",\n".join(ports),
            ");",
            f"  // Which stages hold a valid operand set.",
            f"  reg [{latency}:1] valid;",
            "  always @(posedge clk) valid <= {valid[" + str(latency - 1) + ":1], in_valid};" if latency > 1 else
            "  always @(posedge clk) valid <= in_valid;",
            f"  assign out_valid = valid[{latency}];",
        ]
        lines += self.decls
        lines.append("  always @(posedge clk) begin")
        lines += self.body + chains
        lines.append("  end")
        for name, ref, _ in outputs:
            lines.append(f"  assign {name} = {ref};")
        lines.append("endmodule")
        text = "\n".join(lines) + "\n"
        if any(v.op == "div" for v in u.values):
            text += divider_module(u)
        if any(v.op == "sqrt" for v in u.values):
            text += root_module(u)
        return text


def divider_module(u: Unit) -> str:
    """(a << F) / b truncated toward zero, saturated; b == 0 gives +-max by the sign of a. Long division on the
    magnitudes: the quotient is saturated if it has a bit at W - 1 or above, which is the case exactly when the
    dividend's bits above W - 2 are at least the divisor; otherwise those bits are the remainder so far, and the W - 1
    low quotient bits follow, one shift-and-subtract each."""
    W, F, K = u.W, u.F, u.divide_steps
    name = f"fixed_divide_q{u.I}_{u.F}"
    steps = W - 1
    stages = -(-steps // K)
    L = [f"// Fixed-point divider for Q{u.I}.{u.F}: {u.divide_latency()} clocks, one quotient bit per step, {K} step(s) per stage.",
         f"module {name} (input wire clk, input wire signed [{W - 1}:0] a, input wire signed [{W - 1}:0] b,",
         f"  output reg signed [{W - 1}:0] quotient);",
         f"  wire [{W - 1}:0] a_magnitude = a[{W - 1}] ? -a : a;",
         f"  wire [{W - 1}:0] b_magnitude = b[{W - 1}] ? -b : b;",
         f"  wire [{W + F - 1}:0] dividend = {{a_magnitude, {F}'d0}};",
         f"  wire [{F}:0] dividend_top = dividend[{W + F - 1}:{W - 1}];"]
    # Stage 0 registers.
    L += [f"  reg [{W - 1}:0] r0, d0; reg [{W - 2}:0] low0, q0; reg overflow0, by_zero0, a_negative0, negative0;",
          "  always @(posedge clk) begin",
          f"    r0 <= {{{W - 1 - F}'d0, dividend_top}};" if W - 1 - F > 0 else f"    r0 <= dividend_top[{W - 1}:0];",
          f"    d0 <= b_magnitude; low0 <= dividend[{W - 2}:0]; q0 <= 0;",
          f"    overflow0 <= ({{{W - 1 - F}'d0, dividend_top}} >= b_magnitude);" if W - 1 - F > 0 else
          f"    overflow0 <= (dividend_top >= {{{F + 1 - W}'d0, b_magnitude}});" if F + 1 - W > 0 else
          f"    overflow0 <= (dividend_top >= b_magnitude);",
          f"    by_zero0 <= (b == 0); a_negative0 <= a[{W - 1}]; negative0 <= a[{W - 1}] ^ b[{W - 1}];",
          "  end"]
    bit = W - 2
    for s in range(1, stages + 1):
        p = s - 1
        first, bit = bit, max(bit - K, -1)  # this stage shifts in dividend bits first down to bit + 1
        # Only the dividend bits not yet shifted in travel on.
        L.append(f"  reg [{W - 1}:0] r{s}, d{s}; reg [{W - 2}:0] q{s}; reg overflow{s}, by_zero{s}, a_negative{s}, negative{s};"
                 + (f" reg [{bit}:0] low{s};" if bit >= 0 else ""))
        L.append("  always @(posedge clk) begin : stage" + str(s))
        L.append(f"    reg [{W - 1}:0] r; reg [{W - 2}:0] q;")
        L.append(f"    r = r{p}; q = q{p};")
        for j in range(first, bit, -1):
            L.append(f"    r = {{r[{W - 2}:0], low{p}[{j}]}};")
            L.append(f"    if (r >= d{p}) begin r = r - d{p}; q[{j}] = 1'b1; end")
        if bit >= 0:
            L.append(f"    low{s} <= low{p}[{bit}:0];")
        L.append(f"    r{s} <= r; q{s} <= q; d{s} <= d{p};")
        L.append(f"    overflow{s} <= overflow{p}; by_zero{s} <= by_zero{p}; a_negative{s} <= a_negative{p}; negative{s} <= negative{p};")
        L.append("  end")
    last = stages
    mx, mn = literal(u.max_raw, W), literal(-u.max_raw, W)
    L += ["  always @(posedge clk)",
          f"    quotient <= overflow{last} ? (by_zero{last} ? (a_negative{last} ? {mn} : {mx}) : (negative{last} ? {mn} : {mx}))",
          f"                       : (negative{last} ? -$signed({{1'b0, q{last}}}) : $signed({{1'b0, q{last}}}));",
          "endmodule", ""]
    return "\n".join(L)


def root_module(u: Unit) -> str:
    """sqrt(x << F) rounded to nearest, x <= 0 giving 0, as ScalarTraits<Fixed>::sqrt: two radicand bits per step
    (a root bit each), then one more when the remainder exceeds the root (v > (root + 1/2)^2)."""
    W, F, K = u.W, u.F, u.root_steps
    m = u.root_digits()
    n2 = 2 * m
    RW = m + 3
    stages = -(-m // K)
    name = f"fixed_sqrt_q{u.I}_{u.F}"
    L = [f"// Fixed-point square root for Q{u.I}.{u.F}: {u.root_latency()} clocks, {m} root digits, {K} digit(s) per stage.",
         f"module {name} (input wire clk, input wire signed [{W - 1}:0] x, output reg signed [{W - 1}:0] root);",
         f"  wire [{n2 - 1}:0] radicand = (x <= 0) ? {n2}'d0 : {{{n2 - (W - 1 + F)}'d0, x[{W - 2}:0], {F}'d0}};" if n2 > W - 1 + F else
         f"  wire [{n2 - 1}:0] radicand = (x <= 0) ? {n2}'d0 : {{x[{W - 2}:0], {F}'d0}};",
         f"  reg [{n2 - 1}:0] v0; reg [{RW - 1}:0] rem0; reg [{m - 1}:0] q0;",
         "  always @(posedge clk) begin v0 <= radicand; rem0 <= 0; q0 <= 0; end"]
    digit = m - 1
    for s in range(1, stages + 1):
        p = s - 1
        left = max(digit + 1 - K, 0)  # radicand digits still to come after this stage
        L.append(f"  reg [{RW - 1}:0] rem{s}; reg [{m - 1}:0] q{s};" + (f" reg [{2 * left - 1}:0] v{s};" if left else ""))
        L.append("  always @(posedge clk) begin : stage" + str(s))
        L.append(f"    reg [{RW - 1}:0] rem, trial; reg [{m - 1}:0] q;")
        L.append(f"    rem = rem{p}; q = q{p};")
        for _ in range(K):
            if digit < 0:
                break
            L.append(f"    rem = {{rem[{RW - 3}:0], v{p}[{2 * digit + 1}:{2 * digit}]}};")
            L.append(f"    trial = {{{RW - m - 2}'d0, q, 2'b01}};")
            L.append(f"    if (rem >= trial) begin rem = rem - trial; q = {{q[{m - 2}:0], 1'b1}}; end else q = {{q[{m - 2}:0], 1'b0}};")
            digit -= 1
        L.append(f"    rem{s} <= rem; q{s} <= q;" + (f" v{s} <= v{p}[{2 * left - 1}:0];" if left else ""))
        L.append("  end")
    last = stages
    L += [f"  wire [{m}:0] rounded = ({{{RW - m}'d0, q{last}}} < rem{last}) ? {{1'b0, q{last}}} + 1'b1 : {{1'b0, q{last}}};",
          f"  always @(posedge clk) root <= {{{W - m - 1}'d0, rounded}};" if W > m + 1 else
          f"  always @(posedge clk) root <= rounded[{W - 1}:0];",
          "endmodule", ""]
    return "\n".join(L)
