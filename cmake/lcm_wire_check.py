#!/usr/bin/python3
"""Generates a C++ wire check for LCM types from their .lcm files.

    lcm_wire_check.py --output wire_check.hpp --namespace vslam::wire a.lcm b.lcm ...

For every struct of the given files the header defines Walker<pkg::type_t>,
which walks an encoded message exactly as LCM lays it out (big-endian
primitives; a string is an int32 length that counts the NUL, then the bytes;
arrays row-major, primitive arrays as one block; nested structs without their
fingerprint) without allocating anything, and check<Msg>(data, size, why),
which reads the 8-byte fingerprint first and requires the message to fill the
buffer exactly.

It exists because the decoder lcm-gen 1.3.1 writes resizes a vector to the
claimed count before it looks at the bytes, and checks count * sizeof in int,
which overflows: one small message claiming 5e8 elements crashes the
receiver. The walk rejects, before the decoder runs:
  - a negative array count or string length, or a string length of 0 (the
    decoder would assign length - 1 characters);
  - a string that is not a C string (a NUL inside, or no NUL at the end):
    decoded, it would encode again to other bytes;
  - an array whose count times its element's minimum encoded size is more
    than the bytes left (computed in 64 bits, saturating, never overflowing);
  - an array whose count is more than the whole message's size: elements
    that encode to nothing (an inner dimension of 0) still cost the decoder
    a container each;
  - a field cut off by the end of the buffer, and bytes after the message.

The grammar read is the one the project's .lcm files use: `package`, one or
more `struct` blocks, `const` declarations (skipped), members of the LCM
primitive types, `string` and other structs (qualified or of the same
package), with any number of array dimensions, each an integer literal or an
earlier integer member. Anything else stops the build with the file and line.
"""

import argparse
import os
import re
import sys

PRIMITIVE_SIZES = {
    "int8_t": 1,
    "int16_t": 2,
    "int32_t": 4,
    "int64_t": 8,
    "float": 4,
    "double": 8,
    "boolean": 1,
    "byte": 1,
}
INTEGER_TYPES = ("int8_t", "int16_t", "int32_t", "int64_t")
# A string encodes to at least its int32 length and the NUL.
STRING_MIN_SIZE = 5

TOKEN = re.compile(
    r"\s+|//[^\n]*|/\*.*?\*/|(?P<tok>[A-Za-z_][A-Za-z0-9_.]*|-?[0-9][0-9A-Za-z_.+-]*|\S)",
    re.DOTALL,
)


class LcmError(Exception):
    pass


def tokenize(path, text):
    """(token, line) pairs of a .lcm file, comments dropped."""
    tokens = []
    pos = 0
    while pos < len(text):
        m = TOKEN.match(text, pos)
        line = text.count("\n", 0, pos) + 1
        if not m:
            raise LcmError("%s:%d: cannot read %r" % (path, line, text[pos]))
        if m.group("tok") is not None:
            tokens.append((m.group("tok"), line))
        pos = m.end()
    return tokens


class Member:
    def __init__(self, type_name, name, dims, line):
        self.type_name = type_name  # primitive, "string", or "pkg.struct_t"
        self.name = name
        self.dims = dims  # list of int (literal) or str (member name)
        self.line = line


class Struct:
    def __init__(self, package, name, path):
        self.package = package
        self.name = name
        self.path = path
        self.members = []

    @property
    def full_name(self):
        return self.package + "." + self.name

    @property
    def cpp_name(self):
        return self.package.replace(".", "::") + "::" + self.name


class Parser:
    def __init__(self, path, tokens):
        self.path = path
        self.tokens = tokens
        self.i = 0

    def error(self, message):
        line = self.tokens[min(self.i, len(self.tokens) - 1)][1] if self.tokens else 0
        return LcmError("%s:%d: %s" % (self.path, line, message))

    def peek(self):
        return self.tokens[self.i][0] if self.i < len(self.tokens) else None

    def next(self):
        if self.i >= len(self.tokens):
            raise self.error("unexpected end of file")
        tok = self.tokens[self.i][0]
        self.i += 1
        return tok

    def expect(self, want):
        tok = self.next()
        if tok != want:
            self.i -= 1
            raise self.error("expected %r, found %r" % (want, tok))

    def identifier(self, what):
        tok = self.next()
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.]*", tok):
            self.i -= 1
            raise self.error("expected %s, found %r" % (what, tok))
        return tok

    def parse(self):
        package = ""
        structs = []
        while self.peek() is not None:
            tok = self.next()
            if tok == "package":
                package = self.identifier("a package name")
                self.expect(";")
            elif tok == "struct":
                structs.append(self.parse_struct(package))
            else:
                self.i -= 1
                raise self.error("expected 'package' or 'struct', found %r" % tok)
        return structs

    def parse_struct(self, package):
        if not package:
            raise self.error("a struct outside a package is not supported")
        struct = Struct(package, self.identifier("a struct name"), self.path)
        self.expect("{")
        while self.peek() != "}":
            if self.peek() == "const":
                self.skip_const()
            else:
                self.parse_members(struct)
        self.expect("}")
        return struct

    def skip_const(self):
        # const TYPE NAME = VALUE [, NAME = VALUE]... ;  (not on the wire)
        self.expect("const")
        type_name = self.identifier("a type")
        if type_name not in PRIMITIVE_SIZES or type_name in ("boolean", "byte"):
            raise self.error("const of type %r" % type_name)
        while True:
            self.identifier("a constant name")
            self.expect("=")
            self.next()
            if self.peek() == ",":
                self.next()
                continue
            self.expect(";")
            return

    def parse_members(self, struct):
        line = self.tokens[self.i][1]
        type_name = self.identifier("a member type")
        if type_name in ("enum", "struct", "package"):
            raise self.error("%r inside a struct is not supported" % type_name)
        if type_name not in PRIMITIVE_SIZES and type_name != "string" and "." not in type_name:
            type_name = struct.package + "." + type_name
        while True:
            name = self.identifier("a member name")
            dims = []
            while self.peek() == "[":
                self.next()
                dim = self.next()
                if re.fullmatch(r"[0-9]+", dim):
                    dims.append(int(dim))
                elif re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", dim):
                    dims.append(dim)
                else:
                    self.i -= 1
                    raise self.error("array dimension %r is neither a number nor a member" % dim)
                self.expect("]")
            struct.members.append(Member(type_name, name, dims, line))
            if self.peek() == ",":
                self.next()
                continue
            self.expect(";")
            return


def validate(structs):
    by_name = {s.full_name: s for s in structs}
    if len(by_name) != len(structs):
        raise LcmError("a struct is defined twice")
    for s in structs:
        seen = {}
        for m in s.members:
            where = "%s:%d: %s.%s" % (s.path, m.line, s.full_name, m.name)
            if m.name in seen:
                raise LcmError("%s is declared twice" % where)
            if m.type_name not in PRIMITIVE_SIZES and m.type_name != "string":
                if m.type_name not in by_name:
                    raise LcmError("%s: unknown type %s" % (where, m.type_name))
            for d in m.dims:
                if isinstance(d, str):
                    size_member = seen.get(d)
                    if size_member is None:
                        raise LcmError("%s: dimension %s is not an earlier member" % (where, d))
                    if size_member.type_name not in INTEGER_TYPES or size_member.dims:
                        raise LcmError("%s: dimension %s is not an integer scalar" % (where, d))
            seen[m.name] = m
    # Nested types must not recurse (LCM cannot encode that either).
    state = {}

    def visit(s, chain):
        if state.get(s.full_name) == "done":
            return
        if state.get(s.full_name) == "open":
            raise LcmError("recursive types: " + " -> ".join(chain + [s.full_name]))
        state[s.full_name] = "open"
        for m in s.members:
            if m.type_name in by_name:
                visit(by_name[m.type_name], chain + [s.full_name])
        state[s.full_name] = "done"

    for s in structs:
        visit(s, [])
    return by_name


def min_size(struct, by_name, cache):
    """Smallest encoding of a struct (no fingerprint): variable arrays empty."""
    if struct.full_name in cache:
        return cache[struct.full_name]
    total = 0
    for m in struct.members:
        if any(isinstance(d, str) for d in m.dims):
            continue
        count = 1
        for d in m.dims:
            count *= d
        total += count * element_min_size(m, by_name, cache)
    cache[struct.full_name] = total
    return total


def element_min_size(member, by_name, cache):
    if member.type_name in PRIMITIVE_SIZES:
        return PRIMITIVE_SIZES[member.type_name]
    if member.type_name == "string":
        return STRING_MIN_SIZE
    return min_size(by_name[member.type_name], by_name, cache)


def cpp_type(type_name):
    return type_name.replace(".", "::")


def count_var(name):
    return "n_" + name


RUNTIME = r"""
// Reads an encoded message front to back without allocating.
class Reader {
 public:
  Reader(const void* data, size_t size)
      : data_(static_cast<const uint8_t*>(data)), size_(size), left_(size) {}
  int64_t size() const { return static_cast<int64_t>(size_); }
  int64_t left() const { return static_cast<int64_t>(left_); }

  // Big-endian signed integer of N bytes, sign-extended.
  template <int N>
  bool readInt(int64_t* value) {
    if (left_ < N) return false;
    uint64_t u = 0;
    for (int i = 0; i < N; ++i) u = (u << 8) | data_[i];
    if (N < 8 && (u >> (8 * N - 1)) != 0) u |= ~uint64_t{0} << (8 * N % 64);
    *value = static_cast<int64_t>(u);
    data_ += N;
    left_ -= N;
    return true;
  }
  // The next n bytes are a C string: no NUL before the last, which is NUL.
  bool isCString(int64_t n) const {
    if (n < 1 || n > left()) return false;
    for (int64_t i = 0; i + 1 < n; ++i) {
      if (data_[i] == 0) return false;
    }
    return data_[n - 1] == 0;
  }
  bool skip(int64_t n) {
    if (n < 0 || n > left()) return false;
    data_ += n;
    left_ -= static_cast<size_t>(n);
    return true;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t left_;
};

// a * b for a, b >= 0, saturating at INT64_MAX instead of overflowing.
inline int64_t mulSat(int64_t a, int64_t b) {
  if (a == 0 || b == 0) return 0;
  if (a > std::numeric_limits<int64_t>::max() / b) return std::numeric_limits<int64_t>::max();
  return a * b;
}

inline bool fail(std::string* why, std::string reason) {
  if (why) *why = std::move(reason);
  return false;
}
// Names the enclosing field in a nested failure: "landmark" + "points: ..."
// gives "landmark.points: ...".
inline bool failIn(std::string* why, const std::string& field) {
  if (why) *why = field + "." + *why;
  return false;
}
// Adds the element's index to the field a failure names: "cameras[2]: ...".
inline bool failAt(std::string* why, const char* field, int64_t index) {
  if (why) why->insert(std::char_traits<char>::length(field), "[" + std::to_string(index) + "]");
  return false;
}
inline bool truncated(Reader& r, std::string* why, const char* field, int64_t need) {
  return fail(why, std::string(field) + ": cut off (" + std::to_string(need) + " bytes needed, " +
                       std::to_string(r.left()) + " left)");
}

// A scalar of N bytes that is not needed later.
template <int N>
bool skipScalar(Reader& r, std::string* why, const char* field) {
  return r.skip(N) || truncated(r, why, field, N);
}
// An integer member that sizes an array later.
template <int N>
bool readCount(Reader& r, std::string* why, const char* field, int64_t* value) {
  return r.readInt<N>(value) || truncated(r, why, field, N);
}
// An array's counts, before anything of it is read: each count >= 0, the
// whole array's minimum encoding within the bytes left, and no count (or
// product of leading counts) above the message's size.
inline bool checkArray(Reader& r, std::string* why, const char* field,
                       std::initializer_list<std::pair<const char*, int64_t>> dims,
                       int64_t element_min_size) {
  int64_t elements = 1;
  for (const auto& [name, n] : dims) {
    if (n < 0) {
      return fail(why, std::string(field) + ": count " + name + " = " + std::to_string(n) +
                           " is negative");
    }
    elements = mulSat(elements, n);
    if (elements > r.size()) {
      return fail(why, std::string(field) + ": " + std::to_string(elements) +
                           " elements claimed in a message of " + std::to_string(r.size()) +
                           " bytes");
    }
  }
  const int64_t need = mulSat(elements, element_min_size);
  if (need > r.left()) {
    return fail(why, std::string(field) + ": " + std::to_string(elements) + " elements of >= " +
                         std::to_string(element_min_size) + " bytes need >= " +
                         std::to_string(need) + " bytes, " + std::to_string(r.left()) + " left");
  }
  return true;
}
// A string: int32 length counting the NUL (so >= 1), then that many bytes,
// the last the NUL and no other (a NUL inside would not survive decoding and
// encoding again: the encoder writes the C string).
inline bool skipString(Reader& r, std::string* why, const char* field) {
  int64_t length = 0;
  if (!r.readInt<4>(&length)) return truncated(r, why, field, 4);
  if (length < 1) {
    return fail(why, std::string(field) + ": string length " + std::to_string(length) +
                         " (must count the NUL, so >= 1)");
  }
  if (length > r.left()) return truncated(r, why, field, length);
  if (!r.isCString(length)) {
    return fail(why, std::string(field) + ": not a C string of " + std::to_string(length - 1) +
                         " characters (a NUL inside, or none at the end)");
  }
  return r.skip(length);
}

template <class Msg>
struct Walker;  // specialized below for every type
"""

CHECK = r"""
// True if data[0, size) is exactly one encoded Msg, fingerprint included,
// that the lcm-gen decoder can decode without allocating more than the
// message's size warrants; otherwise false and *why (if not null) says
// which field is wrong and how.
template <class Msg>
bool check(const void* data, size_t size, std::string* why) {
  Reader r(data, size);
  int64_t hash = 0;
  if (!r.readInt<8>(&hash)) {
    return fail(why, "shorter than the 8-byte fingerprint (" + std::to_string(size) + " bytes)");
  }
  if (hash != static_cast<int64_t>(Msg::getHash())) {
    return fail(why, std::string("fingerprint is not ") + Walker<Msg>::kName + "'s");
  }
  if (!Walker<Msg>::walk(r, why)) return false;
  if (r.left() != 0) {
    return fail(why, std::to_string(r.left()) + " bytes after the end of the message");
  }
  return true;
}
"""


def emit_walk(struct, by_name, cache):
    out = []
    w = out.append
    used_as_dim = {d for m in struct.members for d in m.dims if isinstance(d, str)}
    w("inline bool Walker<%s>::walk(Reader& r, std::string* why) {" % struct.cpp_name)
    if not struct.members:
        w("  (void)r;")
        w("  (void)why;")
    for m in struct.members:
        field = '"%s"' % m.name
        if not m.dims:
            if m.name in used_as_dim:
                size = PRIMITIVE_SIZES[m.type_name]
                w("  int64_t %s = 0;" % count_var(m.name))
                w("  if (!readCount<%d>(r, why, %s, &%s)) return false;"
                  % (size, field, count_var(m.name)))
            elif m.type_name in PRIMITIVE_SIZES:
                w("  if (!skipScalar<%d>(r, why, %s)) return false;"
                  % (PRIMITIVE_SIZES[m.type_name], field))
            elif m.type_name == "string":
                w("  if (!skipString(r, why, %s)) return false;" % field)
            else:
                w("  if (!Walker<%s>::walk(r, why)) return failIn(why, %s);"
                  % (cpp_type(m.type_name), field))
            continue
        dims = ", ".join(
            '{"%s", %s}' % (d, count_var(d)) if isinstance(d, str) else '{"%d", %d}' % (d, d)
            for d in m.dims)
        elem = element_min_size(m, by_name, cache)
        w("  {  // %s %s%s" % (m.type_name, m.name, "".join("[%s]" % d for d in m.dims)))
        w("    if (!checkArray(r, why, %s, {%s}, %d)) return false;" % (field, dims, elem))
        count = " * ".join(count_var(d) if isinstance(d, str) else str(d) for d in m.dims)
        # checkArray bounded every product of counts by the message size, so
        # the products below do not overflow.
        if m.type_name in PRIMITIVE_SIZES:
            w("    if (!r.skip(%s * %d)) return truncated(r, why, %s, %s * %d);"
              % (count, elem, field, count, elem))
        else:
            w("    const int64_t elements = %s;" % count)
            w("    for (int64_t i = 0; i < elements; ++i) {")
            if m.type_name == "string":
                w("      if (!skipString(r, why, %s)) return failAt(why, %s, i);" % (field, field))
            else:
                w("      if (!Walker<%s>::walk(r, why)) {" % cpp_type(m.type_name))
                w("        return failIn(why, std::string(%s) + \"[\" + std::to_string(i) + \"]\");"
                  % field)
                w("      }")
            w("    }")
        w("  }")
    w("  return true;")
    w("}")
    return out


def generate(structs, by_name, namespace, sources):
    cache = {}
    out = []
    w = out.append
    w("// Generated by cmake/lcm_wire_check.py from")
    for s in sources:
        w("//   %s" % os.path.basename(s))
    w("// Do not edit. See the generator for what is checked and why.")
    w("#pragma once")
    w("")
    w("#include <cstddef>")
    w("#include <cstdint>")
    w("#include <initializer_list>")
    w("#include <limits>")
    w("#include <string>")
    w("#include <utility>")
    for s in sorted(structs, key=lambda s: s.full_name):
        w("#include <%s/%s.hpp>" % (s.package.replace(".", "/"), s.name))
    w("")
    w("namespace %s {" % namespace)
    out.extend(RUNTIME.strip("\n").split("\n"))
    w("")
    for s in structs:
        w("template <>")
        w("struct Walker<%s> {" % s.cpp_name)
        w('  static constexpr const char* kName = "%s";' % s.full_name)
        w("  // Bytes of the smallest encoding, without the fingerprint.")
        w("  static constexpr int64_t kMinSize = %d;" % min_size(s, by_name, cache))
        w("  static bool walk(Reader& r, std::string* why);")
        w("};")
    w("")
    for s in structs:
        out.extend(emit_walk(s, by_name, cache))
        w("")
    out.extend(CHECK.strip("\n").split("\n"))
    w("")
    w("}  // namespace %s" % namespace)
    return "\n".join(out) + "\n"


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--output", required=True)
    parser.add_argument("--namespace", required=True)
    parser.add_argument("files", nargs="+")
    args = parser.parse_args(argv)
    structs = []
    try:
        for path in sorted(args.files):
            with open(path, encoding="utf-8") as f:
                text = f.read()
            structs.extend(Parser(path, tokenize(path, text)).parse())
        by_name = validate(structs)
    except LcmError as e:
        print("lcm_wire_check.py: error: %s" % e, file=sys.stderr)
        return 1
    text = generate(structs, by_name, args.namespace, sorted(args.files))
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
