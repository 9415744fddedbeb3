//! The per-start secret every request and WebSocket must carry: without it another local user,
//! or a web page open in the same browser, cannot drive the server even though it listens on a
//! port anyone on the machine can reach.

use subtle::ConstantTimeEq;

use crate::error::ViewError;

/// Random bytes in a token: 128 bits, as hex in the URL.
const BYTES: usize = 16;

/// A server's token.
#[derive(Clone)]
pub struct Token {
    hex: String,
}

impl Token {
    /// A new token from the operating system's random source.
    pub fn random() -> Result<Token, ViewError> {
        let mut bytes = [0u8; BYTES];
        getrandom::fill(&mut bytes).map_err(|e| ViewError::Random(e.to_string()))?;
        Ok(Token {
            hex: bytes.iter().map(|b| format!("{b:02x}")).collect(),
        })
    }

    /// The token as it appears in URLs.
    pub fn as_str(&self) -> &str {
        &self.hex
    }

    /// Whether `given` is this token, compared in constant time (the length is no secret).
    pub fn matches(&self, given: &str) -> bool {
        let (a, b) = (self.hex.as_bytes(), given.as_bytes());
        a.len() == b.len() && bool::from(a.ct_eq(b))
    }
}

/// The value of the `token` parameter of a query string, as written (no percent-decoding:
/// a token is hex, so an encoded one is simply wrong).
pub fn in_query(query: Option<&str>) -> Option<&str> {
    query?
        .split('&')
        .find_map(|pair| pair.strip_prefix("token="))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_are_random_hex_and_match_only_themselves() -> Result<(), ViewError> {
        let (a, b) = (Token::random()?, Token::random()?);
        assert_eq!(a.as_str().len(), 2 * BYTES);
        assert!(a.as_str().bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a.as_str(), b.as_str());
        assert!(a.matches(a.as_str()));
        assert!(!a.matches(b.as_str()));
        assert!(!a.matches(&a.as_str()[1..]));
        assert!(!a.matches(""));
        Ok(())
    }

    #[test]
    fn the_token_is_found_among_other_parameters() {
        assert_eq!(in_query(Some("token=ab12")), Some("ab12"));
        assert_eq!(in_query(Some("x=1&token=ab12&y")), Some("ab12"));
        assert_eq!(in_query(Some("notoken=ab12")), None);
        assert_eq!(in_query(None), None);
    }
}
