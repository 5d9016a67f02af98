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
#   select     c ? a : b (xselect for exact values)
# Exact operations keep products wide, as the kernels do for formats of up to 32 bits (ScalarTraits<Fixed>::
# kExactProducts, src/kernel/shapes.hpp): xmul, xadd, xsub give the exact result, as wide as it needs, with the
# operands' fraction bits added (2F, 3F); xlt .. xeq compare such values; round_exact rounds one with 2F fraction bits
# to the format (half up, saturated); exact_sqrt takes the root of one with 2F fraction bits (rounded to nearest,
# clamped), exact_root that of one with 4F, kept exact with 2F; quotient(n, d) is trunc(n * 2^F / d) for n and d with the same fraction bits, clamped, d = 0 giving
# +-max by the sign of n (the divider of `div`, for any widths); shift_quotient(a, e) is a / e for an e whose raw
# value is a power of two and a >= 0 (a quad's extents), a shift.
# Values are signed W = I + F bit integers (the raw field of Fixed) unless exact. Every operation but the bit logic ends in a
# register, so that a new operand set can enter every clock; the scheduler places each operation as early as its
# operands allow and delays values through register chains to the stage where they are used.
# float32.py builds the same graphs on IEEE-754 binary32 values (a Unit subclass with its own operators).

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
    width: int  # W for fixed-point values, 1 for bits, more for exact values
    latency: int
    frac: int = 0  # fraction bits (F for fixed-point values)
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
    exact_mul: int = 0  # exact products (wider than W by W), exact sums and compares
    exact_add: int = 0


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
    def divide_latency(self, quotient_bits: int | None = None) -> int:
        return 2 + -(-(quotient_bits or self.W - 1) // self.divide_steps)

    def root_latency(self, radicand_bits: int | None = None) -> int:
        digits = ((radicand_bits or self.W - 1 + self.F) + 1) // 2
        return 2 + -(-digits // self.root_steps)

    is_float = False  # float32.FloatUnit: the same graphs on IEEE-754 binary32 values

    @property
    def module_name(self) -> str:
        return f"{self.name}_unit_q{self.I}_{self.F}"

    @property
    def format_name(self) -> str:
        return f"Q{self.I}.{self.F}"

    @property
    def model_type(self) -> str:
        """The C++ type whose kernel functions the unit reproduces."""
        return f"Fixed<{self.I}, {self.F}>"

    # ---- building the graph ----
    def _value(self, op: str, args: tuple, width: int, latency: int, param: int = 0) -> Value:
        for a in args:
            assert a.unit is self
        v = Value(self, len(self.values), op, args, width, latency, param=param, frac=self.F if width == self.W else 0)
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
        assert all(a.width == self.W for a in args), "a fixed-point operation was given a bit or an exact value"

    def add(self, a, b): self._fixed(a, b); return self._value("add", (a, b), self.W, 1)
    def sub(self, a, b): self._fixed(a, b); return self._value("sub", (a, b), self.W, 1)
    def mul(self, a, b): self._fixed(a, b); return self._value("mul", (a, b), self.W, 2)
    def div(self, a, b):
        self._fixed(a, b)
        v = self._value("div", (a, b), self.W, self.divide_latency())
        v.param = self.W - 1  # quotient bits
        return v

    def sqrt(self, a):
        self._fixed(a)
        return self._value("sqrt", (a,), self.W, self.root_latency())

    # ---- exact operations (products kept wide) ----
    def xmul(self, a, b):
        v = self._value("xmul", (a, b), a.width + b.width, 1)
        v.frac = a.frac + b.frac
        return v

    def _xsum(self, op, a, b):
        assert a.frac == b.frac, f"{op} of values with {a.frac} and {b.frac} fraction bits"
        v = self._value(op, (a, b), max(a.width, b.width) + 1, 1)
        v.frac = a.frac
        return v

    def xadd(self, a, b): return self._xsum("xadd", a, b)
    def xsub(self, a, b): return self._xsum("xsub", a, b)

    def _xcmp(self, op, a, b):
        assert a.frac == b.frac
        return self._value(op, (a, b), 1, 1)

    def xlt(self, a, b): return self._xcmp("lt", a, b)
    def xle(self, a, b): return self._xcmp("le", a, b)
    def xgt(self, a, b): return self._xcmp("lt", b, a)
    def xge(self, a, b): return self._xcmp("le", b, a)
    def xeq(self, a, b): return self._xcmp("eq", a, b)

    def xzero(self, frac: int):
        v = self._value("const", (), 1 + 1, 0, 0)
        v.frac = frac
        return v

    def round_exact(self, v):
        assert v.frac == 2 * self.F
        return self._value("round", (v,), self.W, 1)

    def exact_sqrt(self, v):
        assert v.frac == 2 * self.F
        return self._value("xsqrt", (v,), self.W, self.root_latency(v.width - 1))  # the magnitude of a positive v

    def exact_root(self, v):
        """The root of an exact value with an even number of fraction bits, rounded to nearest, kept exact (half the
        fraction bits; 0 for v <= 0)."""
        assert v.frac % 2 == 0
        digits = v.width // 2
        r = self._value("xroot", (v,), digits + 2, self.root_latency(v.width - 1))
        r.frac = v.frac // 2
        return r

    def quotient(self, n, d, quotient_bits: int | None = None):
        """trunc(n * 2^F / d) clamped; quotient_bits < W - 1 where the result is known to be small when it matters."""
        assert n.frac == d.frac
        bits = quotient_bits or self.W - 1
        v = self._value("quotient", (n, d), self.W, self.divide_latency(bits))
        v.param = bits
        return v

    def shift_quotient(self, a, extent):
        """trunc(a * 2^F / (extent * 2^F)) for a >= 0 and an extent whose raw value is a power of two: a >> log2."""
        assert a.frac == 2 * self.F and extent.width == self.W
        return self._value("shift_quotient", (a, extent), self.W, 2)

    def xdot(self, a, b):
        """An exact dot product (the order does not matter: nothing is rounded)."""
        return self.xadd(self.xadd(self.xmul(a[0], b[0]), self.xmul(a[1], b[1])), self.xmul(a[2], b[2]))

    def xcross(self, a, b):
        return (self.xsub(self.xmul(a[1], b[2]), self.xmul(a[2], b[1])),
                self.xsub(self.xmul(a[2], b[0]), self.xmul(a[0], b[2])),
                self.xsub(self.xmul(a[0], b[1]), self.xmul(a[1], b[0])))

    def xselect(self, c, a, b):
        """c ? a : b for exact values with the same fraction bits (sign-extended to the wider)."""
        assert c.is_bit and a.frac == b.frac and not a.is_bit and not b.is_bit
        v = self._value("select", (c, a, b), max(a.width, b.width), 1)
        v.frac = a.frac
        return v

    def bit_select(self, c, a, b):
        """c ? a : b for bits."""
        return self.or_(self.and_(c, a), self.and_(self.not_(c), b))
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
            elif v.op in ("div", "quotient", "shift_quotient"): c.div += 1
            elif v.op in ("sqrt", "xsqrt", "xroot"): c.sqrt += 1
            elif v.op == "xmul": c.exact_mul += 1
            elif v.op in ("xadd", "xsub", "round"): c.exact_add += 1
            elif v.op in ("lt", "le", "eq", "min", "max"): c.compare += 1
        return c

    def latency(self) -> int:
        return max(v.ready for _, v in self.outputs)

    # ---- Verilog ----
    def verilog(self) -> str:
        return Emitter(self).emit()

    def verilog_parts(self) -> tuple[str, dict[str, str]]:
        """The unit's module and, apart, the submodules it instantiates by name (dividers, roots), so that several
        units can share one file without defining a submodule twice."""
        emitter = Emitter(self)
        text = emitter.emit()
        main = text[: len(text) - len("".join(emitter.modules.values()))]
        return main, dict(emitter.modules)


class Emitter:
    def __init__(self, unit: Unit):
        self.u = unit
        self.delays: dict[int, int] = {}  # value index -> longest delay chain needed
        self.body: list[str] = []
        self.decls: list[str] = []
        self.modules: dict[str, str] = {}  # submodules (dividers, roots) by name
        self.uses_loop = False

    def module(self, make, *args) -> str:
        name, text = make(*args)
        self.modules.setdefault(name, text)
        return name

    def ref(self, v: Value, stage: int) -> str:
        """The name under which v is valid at `stage`."""
        if v.op == "const":
            return f"({literal(v.param, v.width)})"
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
        rng = "" if v.is_bit else f"[{v.width - 1}:0] "
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
        elif v.op in ("div", "quotient"):
            wn, wd = v.args[0].width, v.args[1].width
            module = self.module(divider_module, u, wn, wd, v.param)
            self.decls.append(f"  {module} {n}_divider(.clk(clk), .n({a[0]}), .d({a[1]}), .quotient({n}));")
            self.decls[-2] = f"  wire signed [{W - 1}:0] {n};"
        elif v.op == "sqrt":
            # x << F: the root of a value with 2F fraction bits, as for exact_sqrt.
            module = self.module(root_module, u, W + F)
            self.decls.append(f"  {module} {n}_root(.clk(clk), .v({{{a[0]}, {F}'d0}}), .root({n}));")
            self.decls[-2] = f"  wire signed [{W - 1}:0] {n};"
        elif v.op in ("xsqrt", "xroot"):
            module = self.module(root_module, u, v.args[0].width, v.op == "xroot")
            self.decls.append(f"  {module} {n}_root(.clk(clk), .v({a[0]}), .root({n}));")
            self.decls[-2] = f"  wire signed [{v.width - 1}:0] {n};"
        elif v.op == "xmul":
            self.body.append(f"    {n} <= {a[0]} * {a[1]};")
        elif v.op in ("xadd", "xsub"):
            self.body.append(f"    {n} <= {a[0]} {'+' if v.op == 'xadd' else '-'} {a[1]};")
        elif v.op == "round":
            w, shift = v.args[0].width, v.args[0].frac - F
            self.decls.append(f"  wire signed [{w}:0] {n}_rounded = {a[0]} + {literal(1 << (shift - 1), w + 1)};")
            self.decls.append(f"  wire signed [{w - shift}:0] {n}_shifted = {n}_rounded[{w}:{shift}];")
            self.body.append(f"    {n} <= {self.saturate(n + '_shifted', w + 1 - shift)};")
        elif v.op == "shift_quotient":
            w = v.args[0].width
            self.decls.append(f"  reg signed [{w - 1}:0] {n}_value; reg [{max(1, (W - 1).bit_length()) - 1}:0] {n}_log2;")
            self.decls.append(f"  wire signed [{w - 1}:0] {n}_shifted = {n}_value >>> {n}_log2;")
            self.body.append(f"    {n}_value <= {a[0]};")
            self.body.append(f"    {n}_log2 <= 0;")
            self.body.append(f"    for (k = 0; k < {W}; k = k + 1) if ({a[1]}[k]) {n}_log2 <= k;")
            self.body.append(f"    {n} <= {self.saturate(n + '_shifted', w)};")
            self.uses_loop = True
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
            rng = "" if v.is_bit else f"[{v.width - 1}:0] "
            for k in range(1, depth + 1):
                self.decls.append(f"  reg {sign}{rng}{v.name}_d{k};")
                chains.append(f"    {v.name}_d{k} <= {v.name if k == 1 else f'{v.name}_d{k - 1}'};")
        ports = ["  input wire clk", "  input wire in_valid"]
        ports += [f"  input wire signed [{W - 1}:0] {name}" for name, _ in u.inputs]
        ports.append("  output wire out_valid")
        for name, _, v in outputs:
            ports.append(f"  output wire {'' if v.is_bit else f'signed [{W - 1}:0] '}{name}")
        lines = [
            f"// {u.name} unit in {u.format_name} (generated by tools/hardware/units.py; do not edit): one operand set per clock,",
            f"// results {latency} clocks later. Bit-exact with the kernel function on {u.model_type}.",
            f"module {u.module_name} (",
            ",\n".join(ports),
            ");",
            f"  // Which stages hold a valid operand set.",
            f"  reg [{latency}:1] valid;",
            "  always @(posedge clk) valid <= {valid[" + str(latency - 1) + ":1], in_valid};" if latency > 1 else
            "  always @(posedge clk) valid <= in_valid;",
            f"  assign out_valid = valid[{latency}];",
        ]
        if self.uses_loop:
            lines.append("  integer k;")
        lines += self.decls
        lines.append("  always @(posedge clk) begin")
        lines += self.body + chains
        lines.append("  end")
        for name, ref, _ in outputs:
            lines.append(f"  assign {name} = {ref};")
        lines.append("endmodule")
        return "\n".join(lines) + "\n" + "".join(self.modules.values())


def divider_module(u: Unit, wn: int, wd: int, qb: int):
    """trunc(n * 2^F / d) toward zero for signed n (wn bits) and d (wd bits), clamped to +-max; d = 0 gives +-max by
    the sign of n. Long division on the magnitudes: the quotient is clamped if it has a bit at qb or above, which is
    the case exactly when the shifted dividend's bits from qb up are at least the divisor; otherwise those bits are
    the remainder so far, and the qb low quotient bits follow, one shift-and-subtract each (K per stage). With
    qb = W - 1 this is Fixed's operator/ and exact_quotient; a smaller qb serves quotients known to be small
    wherever they are used (a hit's barycentrics, at most 1)."""
    W, F, K = u.W, u.F, u.divide_steps
    name = f"fixed_divide_q{u.I}_{u.F}_n{wn}_d{wd}_q{qb}"
    wN = wn + F  # the shifted dividend's magnitude
    stages = -(-qb // K)
    rw = wd + 1  # remainder: below the divisor, one bit shifted in
    top_w = wN - qb
    L = [f"// Divider for Q{u.I}.{u.F}: {wn}-bit dividend times 2^{F} over a {wd}-bit divisor, {qb} quotient bits, "
         f"{2 + stages} clocks.",
         f"module {name} (input wire clk, input wire signed [{wn - 1}:0] n, input wire signed [{wd - 1}:0] d,",
         f"  output reg signed [{W - 1}:0] quotient);",
         f"  wire [{wn - 1}:0] n_magnitude = n[{wn - 1}] ? -n : n;",
         f"  wire [{wd - 1}:0] d_magnitude = d[{wd - 1}] ? -d : d;",
         f"  wire [{wN - 1}:0] dividend = {{n_magnitude, {F}'d0}};"]
    if top_w > 0:
        tw = max(top_w, rw)
        L.append(f"  wire [{tw - 1}:0] dividend_top = {{{tw - top_w}'d0, dividend[{wN - 1}:{qb}]}};" if tw > top_w else
                 f"  wire [{tw - 1}:0] dividend_top = dividend[{wN - 1}:{qb}];")
        overflow = f"(dividend_top >= {{{tw - wd}'d0, d_magnitude}})"
        first = f"dividend_top[{rw - 1}:0]"
    else:
        overflow = "(d_magnitude == 0)"
        first = "0"
    L += [f"  reg [{rw - 1}:0] r0; reg [{wd - 1}:0] d0; reg [{qb - 1}:0] low0, q0; reg overflow0, by_zero0, n_negative0, negative0;",
          "  always @(posedge clk) begin",
          f"    r0 <= {first}; d0 <= d_magnitude; low0 <= dividend[{qb - 1}:0]; q0 <= 0; overflow0 <= {overflow};",
          f"    by_zero0 <= (d == 0); n_negative0 <= n[{wn - 1}]; negative0 <= n[{wn - 1}] ^ d[{wd - 1}];",
          "  end"]
    bit = qb - 1
    for s in range(1, stages + 1):
        p = s - 1
        first_bit, bit = bit, max(bit - K, -1)  # this stage shifts in dividend bits first_bit down to bit + 1
        # Only the dividend bits not yet shifted in travel on.
        L.append(f"  reg [{rw - 1}:0] r{s}; reg [{wd - 1}:0] d{s}; reg [{qb - 1}:0] q{s}; reg overflow{s}, by_zero{s}, n_negative{s}, negative{s};"
                 + (f" reg [{bit}:0] low{s};" if bit >= 0 else ""))
        L.append("  always @(posedge clk) begin : stage" + str(s))
        L.append(f"    reg [{rw - 1}:0] r; reg [{qb - 1}:0] q;")
        L.append(f"    r = r{p}; q = q{p};")
        for j in range(first_bit, bit, -1):
            L.append(f"    r = {{r[{rw - 2}:0], low{p}[{j}]}};")
            L.append(f"    if (r >= {{1'b0, d{p}}}) begin r = r - {{1'b0, d{p}}}; q[{j}] = 1'b1; end")
        if bit >= 0:
            L.append(f"    low{s} <= low{p}[{bit}:0];")
        L.append(f"    r{s} <= r; q{s} <= q; d{s} <= d{p};")
        L.append(f"    overflow{s} <= overflow{p}; by_zero{s} <= by_zero{p}; n_negative{s} <= n_negative{p}; negative{s} <= negative{p};")
        L.append("  end")
    last = stages
    mx, mn = literal(u.max_raw, W), literal(-u.max_raw, W)
    q = f"{{{W - qb}'d0, q{last}}}" if W > qb else f"q{last}[{W - 1}:0]"
    L += ["  always @(posedge clk)",
          f"    quotient <= overflow{last} ? (by_zero{last} ? (n_negative{last} ? {mn} : {mx}) : (negative{last} ? {mn} : {mx}))",
          f"                       : (negative{last} ? -$signed({q}) : $signed({q}));",
          "endmodule", ""]
    return name, "\n".join(L)


def root_module(u: Unit, wv: int, exact: bool = False):
    """The root of a signed value v (wv bits) with 2F fraction bits, as a value with F: isqrt(v) rounded to nearest
    (one more where the remainder exceeds the root: v > (root + 1/2)^2), 0 for v <= 0, clamped to the range. Two
    radicand bits per digit, K digits per stage. Fixed's sqrt(x) is the root of x << F. `exact`: the rounded root
    as it is, m + 2 bits (exact_root), not clamped."""
    W, K = u.W, u.root_steps
    n = wv - 1  # the magnitude of a positive v
    m = (n + 1) // 2
    n2 = 2 * m
    RW = m + 3
    stages = -(-m // K)
    name = f"fixed_sqrt_q{u.I}_{u.F}_r{wv}" + ("_exact" if exact else "")
    L = [f"// Square root for Q{u.I}.{u.F} of a {wv}-bit value: {2 + stages} clocks, {m} root digits, {K} digit(s) per stage.",
         f"module {name} (input wire clk, input wire signed [{wv - 1}:0] v, output reg signed [{(m + 1 if exact else W - 1)}:0] root);",
         f"  wire [{n2 - 1}:0] radicand = (v <= 0) ? {n2}'d0 : " + (f"{{{n2 - n}'d0, v[{n - 1}:0]}};" if n2 > n else f"v[{n - 1}:0];"),
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
    mx = literal(u.max_raw, W)
    rounded = f"  wire [{m}:0] rounded = ({{{RW - m}'d0, q{last}}} < rem{last}) ? {{1'b0, q{last}}} + 1'b1 : {{1'b0, q{last}}};"
    if exact:
        return name, "\n".join(L + [rounded, "  always @(posedge clk) root <= {1'b0, rounded};", "endmodule", ""])
    L += [rounded,
          f"  always @(posedge clk) root <= (rounded > {m + 1}'d{u.max_raw}) ? {mx} : " +
          (f"{{{W - m - 1}'d0, rounded}};" if W > m + 1 else f"rounded[{W - 1}:0];") if (1 << (m + 1)) > u.max_raw else
          f"  always @(posedge clk) root <= {{{W - m - 1}'d0, rounded}};",
          "endmodule", ""]
    return name, "\n".join(L)
