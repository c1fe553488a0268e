//! The DevTools pipe's framing: each message is one JSON text followed by a
//! NUL byte, in both directions. JSON never holds a raw NUL (a NUL in a
//! string is written `\u0000`), so the NUL cannot occur inside a message.

use serde_json::Value;

/// The byte that ends every message on the pipe.
pub const TERMINATOR: u8 = 0;

/// The longest message the reader accepts, terminator excluded: far more
/// than a page's pixels or a GIF as base64, and a bound on what a broken
/// browser could make the reader hold.
pub const MAX_MESSAGE_BYTES: usize = 256 << 20;

/// What was wrong with the bytes on the pipe.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum FramingError {
    /// No terminator within [`MAX_MESSAGE_BYTES`].
    #[error("a message of over {limit} bytes without its NUL terminator")]
    TooLong {
        /// The limit that was passed.
        limit: usize,
    },
    /// A terminated message that is not one JSON object.
    #[error("not a JSON object ({error}): {start:?}")]
    NotJson {
        /// What the JSON reader said.
        error: String,
        /// The message's first bytes, for the reader of the error.
        start: String,
    },
}

/// A message as it goes on the pipe: its JSON, then the terminator.
pub fn encode(message: &Value) -> Vec<u8> {
    let mut bytes = serde_json::to_vec(message).expect("a JSON value always serialises");
    bytes.push(TERMINATOR);
    bytes
}

/// One message's bytes (without the terminator) read as a JSON object.
pub fn decode(frame: &[u8]) -> Result<Value, FramingError> {
    let not_json = |error: String| FramingError::NotJson {
        error,
        start: String::from_utf8_lossy(&frame[..frame.len().min(200)]).into_owned(),
    };
    match serde_json::from_slice::<Value>(frame) {
        Ok(value @ Value::Object(_)) => Ok(value),
        Ok(_) => Err(not_json("not an object".into())),
        Err(error) => Err(not_json(error.to_string())),
    }
}

/// Cuts the byte stream read from the pipe into messages, whatever the
/// sizes of the reads: a message may arrive in many reads, and one read may
/// hold many messages.
#[derive(Debug)]
pub struct Splitter {
    /// Bytes of the message not yet terminated.
    pending: Vec<u8>,
    limit: usize,
}

impl Default for Splitter {
    fn default() -> Self {
        Self::new(MAX_MESSAGE_BYTES)
    }
}

impl Splitter {
    /// A splitter that refuses messages longer than `limit` bytes.
    pub fn new(limit: usize) -> Self {
        Splitter {
            pending: Vec::new(),
            limit,
        }
    }

    /// Takes the bytes of one read; returns the messages they complete, in
    /// order, without terminators. After an error the stream cannot be
    /// trusted to be in step, so the caller stops reading.
    pub fn push(&mut self, mut bytes: &[u8]) -> Result<Vec<Vec<u8>>, FramingError> {
        let mut messages = Vec::new();
        while let Some(end) = bytes.iter().position(|&b| b == TERMINATOR) {
            self.take(&bytes[..end])?;
            messages.push(std::mem::take(&mut self.pending));
            bytes = &bytes[end + 1..];
        }
        self.take(bytes)?;
        Ok(messages)
    }

    /// Bytes of a message not yet terminated (a message cut off when the
    /// pipe closed).
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    fn take(&mut self, bytes: &[u8]) -> Result<(), FramingError> {
        if self.pending.len() + bytes.len() > self.limit {
            return Err(FramingError::TooLong { limit: self.limit });
        }
        self.pending.extend_from_slice(bytes);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_message_is_its_json_then_one_nul() {
        let bytes = encode(&json!({"id": 7, "method": "Page.enable"}));
        assert_eq!(bytes.last(), Some(&TERMINATOR));
        assert_eq!(bytes.iter().filter(|&&b| b == TERMINATOR).count(), 1);
        assert_eq!(
            decode(&bytes[..bytes.len() - 1]).unwrap(),
            json!({"id": 7, "method": "Page.enable"})
        );
    }

    #[test]
    fn a_nul_inside_a_string_is_escaped_not_a_terminator() {
        let message = json!({"id": 1, "params": {"expression": "'a\u{0}b'"}});
        let bytes = encode(&message);
        assert_eq!(
            bytes.iter().position(|&b| b == TERMINATOR),
            Some(bytes.len() - 1)
        );
        let mut splitter = Splitter::default();
        let frames = splitter.push(&bytes).unwrap();
        assert_eq!(frames.len(), 1);
        assert_eq!(decode(&frames[0]).unwrap(), message);
    }

    #[test]
    fn messages_split_the_same_however_the_reads_cut_them() {
        let messages: Vec<Value> = (0..5)
            .map(|id| json!({"id": id, "result": {"text": "x".repeat(id * 37)}}))
            .collect();
        let stream: Vec<u8> = messages.iter().flat_map(encode).collect();
        for read_size in [1, 2, 3, 7, 64, stream.len()] {
            let mut splitter = Splitter::default();
            let mut got = Vec::new();
            for read in stream.chunks(read_size) {
                for frame in splitter.push(read).unwrap() {
                    got.push(decode(&frame).unwrap());
                }
            }
            assert_eq!(got, messages, "reads of {read_size} bytes");
            assert_eq!(splitter.pending(), 0);
        }
    }

    #[test]
    fn an_unterminated_message_waits_for_its_end() {
        let mut splitter = Splitter::default();
        assert!(splitter.push(b"{\"id\":").unwrap().is_empty());
        assert_eq!(splitter.pending(), 6);
        let frames = splitter.push(b"3}\0{").unwrap();
        assert_eq!(frames, vec![b"{\"id\":3}".to_vec()]);
        assert_eq!(splitter.pending(), 1);
    }

    #[test]
    fn empty_frames_and_non_objects_are_not_messages() {
        let mut splitter = Splitter::default();
        let frames = splitter.push(b"\0[1,2]\0{broken\0").unwrap();
        assert_eq!(frames.len(), 3);
        for frame in &frames {
            assert!(matches!(decode(frame), Err(FramingError::NotJson { .. })));
        }
    }

    #[test]
    fn a_message_over_the_limit_is_refused() {
        let mut splitter = Splitter::new(8);
        assert_eq!(splitter.push(b"{\"a\":1}\0").unwrap().len(), 1);
        assert_eq!(
            splitter.push(b"{\"ab\":"),
            Ok(Vec::new()),
            "six bytes pending"
        );
        assert_eq!(
            splitter.push(b"123}"),
            Err(FramingError::TooLong { limit: 8 })
        );
    }
}
