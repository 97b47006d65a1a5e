//! Credentials: random session ids and tokens, where a request presents its credential, and
//! constant-time comparison.
//!
//! A session's token opens that session's endpoints and streams; the admin key (when configured)
//! guards creating, listing and deleting sessions and opens every session. A credential comes as
//! `Authorization: Bearer <secret>` or, for browsers' WebSockets which cannot set headers, as the
//! `token` query parameter.

use axum::http::HeaderMap;
use axum::http::header::AUTHORIZATION;
use rand::RngCore;
use subtle::ConstantTimeEq;

/// Bytes of randomness in a session token (256 bits).
const TOKEN_BYTES: usize = 32;
/// Bytes of randomness in a session id (64 bits; ids are not secrets).
const ID_BYTES: usize = 8;

fn random_hex(n: usize) -> String {
    let mut bytes = vec![0u8; n];
    // ThreadRng is a CSPRNG seeded from the operating system.
    rand::rng().fill_bytes(&mut bytes);
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A new session token: 256 random bits as 64 hex digits.
pub fn new_token() -> String {
    random_hex(TOKEN_BYTES)
}

/// A new session id: 64 random bits as 16 hex digits.
pub fn new_session_id() -> String {
    random_hex(ID_BYTES)
}

/// Whether two secrets are equal, in time independent of where they differ.
pub fn same_secret(expected: &str, presented: &str) -> bool {
    // Lengths are not secret (tokens have a fixed length); contents are compared in constant time.
    expected.len() == presented.len() && bool::from(expected.as_bytes().ct_eq(presented.as_bytes()))
}

/// The credential a request presents: the bearer token of the `Authorization` header, else the
/// `token` query parameter.
pub fn presented(headers: &HeaderMap, query: Option<&str>) -> Option<String> {
    if let Some(v) = headers.get(AUTHORIZATION).and_then(|v| v.to_str().ok()) {
        let v = v.trim();
        if let Some(rest) = v.get(..7)
            && rest.eq_ignore_ascii_case("bearer ")
        {
            return Some(v[7..].trim().to_string());
        }
        return Some(String::new());
    }
    query?
        .split('&')
        .filter_map(|kv| kv.split_once('='))
        .find(|(k, _)| *k == "token")
        .map(|(_, v)| percent_decode(v))
}

/// Decodes `%XX` escapes and `+` (query-string form); invalid escapes are kept as they are.
fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'%' if i + 2 < b.len() => {
                let hex = std::str::from_utf8(&b[i + 1..i + 3])
                    .ok()
                    .and_then(|h| u8::from_str_radix(h, 16).ok());
                match hex {
                    Some(v) => {
                        out.push(v);
                        i += 3;
                    }
                    None => {
                        out.push(b'%');
                        i += 1;
                    }
                }
            }
            b'+' => {
                out.push(b' ');
                i += 1;
            }
            c => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    #[test]
    fn tokens_are_long_random_and_distinct() {
        let (a, b) = (new_token(), new_token());
        assert_eq!(a.len(), 64);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
        assert_eq!(new_session_id().len(), 16);
    }

    #[test]
    fn secrets_compare_exactly() {
        let t = new_token();
        assert!(same_secret(&t, &t.clone()));
        assert!(!same_secret(&t, &t[..63]));
        let mut other = t.clone().into_bytes();
        other[63] = if other[63] == b'0' { b'1' } else { b'0' };
        assert!(!same_secret(&t, std::str::from_utf8(&other).unwrap()));
        assert!(!same_secret(&t, ""));
    }

    #[test]
    fn credentials_come_from_the_header_or_the_query() {
        let mut h = HeaderMap::new();
        assert_eq!(presented(&h, None), None);
        assert_eq!(
            presented(&h, Some("a=1&token=abc%2Bd")).as_deref(),
            Some("abc+d")
        );
        h.insert(AUTHORIZATION, HeaderValue::from_static("Bearer  xyz "));
        assert_eq!(presented(&h, Some("token=abc")).as_deref(), Some("xyz"));
        h.insert(AUTHORIZATION, HeaderValue::from_static("Basic Zm9v"));
        assert_eq!(
            presented(&h, None).as_deref(),
            Some(""),
            "a wrong scheme is a wrong credential"
        );
        assert_eq!(percent_decode("100%"), "100%");
    }
}
