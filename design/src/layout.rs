//! The layout of the JSON answers: the top-level object one key per line, everything inside it
//! on one line with a space after each `:` and `,`: one line per item of the answer, and the
//! scan stays a short block.

use std::io;

use serde::Serialize;
use serde_json::ser::Formatter;
use serde_json::Value;

/// `value` as text in the [`Layout`] (no final newline).
pub(crate) fn laid_out(value: &Value) -> String {
    let mut out = Vec::new();
    let mut writer = serde_json::Serializer::with_formatter(&mut out, Layout { depth: 0 });
    value
        .serialize(&mut writer)
        .expect("a JSON value serializes into memory");
    String::from_utf8(out).expect("serde_json writes UTF-8")
}

/// The top-level object one key per line, everything inside it on one line.
struct Layout {
    depth: usize,
}

impl Formatter for Layout {
    fn begin_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth += 1;
        w.write_all(b"[")
    }

    fn end_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth -= 1;
        w.write_all(b"]")
    }

    fn begin_array_value<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        w.write_all(if first { b"" } else { b", " })
    }

    fn begin_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth += 1;
        w.write_all(b"{")
    }

    fn end_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.depth -= 1;
        w.write_all(if self.depth == 0 { b"\n}" } else { b"}" })
    }

    fn begin_object_key<W: ?Sized + io::Write>(&mut self, w: &mut W, first: bool) -> io::Result<()> {
        let separator: &[u8] = match (self.depth, first) {
            (1, true) => b"\n  ",
            (1, false) => b",\n  ",
            (_, true) => b"",
            (_, false) => b", ",
        };
        w.write_all(separator)
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        w.write_all(b": ")
    }
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    #[test]
    fn the_layout_puts_each_top_level_key_on_its_line() {
        let value = json!({"a": {"x": 1.0, "y": [f64::INFINITY, 2.5e-7]}, "b": [], "c": "q\"uote"});
        let text = laid_out(&value);
        assert_eq!(
            text,
            "{\n  \"a\": {\"x\": 1.0, \"y\": [null, 2.5e-7]},\n  \"b\": [],\n  \"c\": \"q\\\"uote\"\n}"
        );
        assert_eq!(serde_json::from_str::<Value>(&text).unwrap()["c"], "q\"uote");
    }
}
