//! The names the server answers to. A server listening on every interface (`--bind 0.0.0.0`
//! or `::`) prints its URL with this machine's host name, since no browser elsewhere can open
//! 0.0.0.0; every request's Host must then be that name, a loopback name or an IP address, so
//! that a page whose own name was pointed at this machine (DNS rebinding) is refused even
//! before its token would be.
//!
//! Any IP address is accepted as the Host: a browser sends one only when it was told to open
//! that address, so it reached this server under it, and no other site's page can share that
//! origin. The port is not checked, so an SSH tunnel or a proxy may listen on another one.

use std::net::{IpAddr, Ipv4Addr, Ipv6Addr};

/// The longest host name a URL carries (RFC 1035).
const MAX_NAME: usize = 253;

/// This machine's host name (`uname`'s node name) when a URL can carry it: letters, digits
/// and hyphens in dot-separated labels. None on other systems or for any other name.
pub fn machine_name() -> Option<String> {
    let name = node_name()?;
    is_host_name(&name).then(|| name.to_ascii_lowercase())
}

#[cfg(unix)]
fn node_name() -> Option<String> {
    let uname = rustix::system::uname();
    uname.nodename().to_str().ok().map(str::to_string)
}

#[cfg(not(unix))]
fn node_name() -> Option<String> {
    None
}

/// Whether `name` is a DNS host name: labels of 1 to 63 letters, digits and inner hyphens,
/// not all digits (that would read as an address).
fn is_host_name(name: &str) -> bool {
    let label = |l: &str| {
        (1..=63).contains(&l.len())
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
            && !l.starts_with('-')
            && !l.ends_with('-')
    };
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name.split('.').all(label)
        && !name.bytes().all(|b| b.is_ascii_digit() || b == b'.')
}

/// The host of the URL of a server listening on `ip`: the address itself, in brackets for
/// IPv6, unless it is unspecified (every interface): then `machine` (this machine's name), or
/// failing that the loopback address of its family.
pub fn url_host(ip: IpAddr, machine: Option<&str>) -> String {
    match (ip.is_unspecified(), machine) {
        (true, Some(name)) => name.to_string(),
        (true, None) => match ip {
            IpAddr::V4(_) => Ipv4Addr::LOCALHOST.to_string(),
            IpAddr::V6(_) => format!("[{}]", Ipv6Addr::LOCALHOST),
        },
        (false, _) => match ip {
            IpAddr::V4(a) => a.to_string(),
            IpAddr::V6(a) => format!("[{a}]"),
        },
    }
}

/// The Host header values a server accepts ([module documentation](self)).
#[derive(Clone, Debug)]
pub struct Hosts {
    /// Lower-case names: `localhost` and the URL's host when it is a name.
    names: Vec<String>,
}

impl Hosts {
    /// The hosts of a server whose URL names `url_host` ([`url_host`]).
    pub fn new(url_host: &str) -> Hosts {
        let mut names = vec!["localhost".to_string()];
        let own = url_host.to_ascii_lowercase();
        if !names.contains(&own) && is_host_name(&own) {
            names.push(own);
        }
        Hosts { names }
    }

    /// Whether `host` (a Host header: a name or an address, and maybe a port) is one this
    /// server answers to.
    pub fn allows(&self, host: &str) -> bool {
        match split_port(host) {
            Some(Authority::Address) => true,
            Some(Authority::Name(name)) => {
                let name = name.strip_suffix('.').unwrap_or(name);
                self.names.iter().any(|n| n.eq_ignore_ascii_case(name))
            }
            None => false,
        }
    }
}

/// What a Host header names.
enum Authority<'a> {
    /// An IP address.
    Address,
    /// A name (not checked to be a host name).
    Name(&'a str),
}

/// A Host header less its port; None when it is malformed (an empty name, a port that is not
/// digits, a bracketed part that is not an IPv6 address).
fn split_port(host: &str) -> Option<Authority<'_>> {
    let port_ok = |p: &str| p.is_empty() || p.strip_prefix(':').is_some_and(is_port);
    if let Some(rest) = host.strip_prefix('[') {
        let (inside, after) = rest.split_once(']')?;
        return (inside.parse::<Ipv6Addr>().is_ok() && port_ok(after))
            .then_some(Authority::Address);
    }
    let name = match host.rsplit_once(':') {
        Some((name, port)) if is_port(port) => name,
        Some(_) => return None,
        None => host,
    };
    if name.is_empty() || name.contains(':') {
        return None;
    }
    Some(match name.parse::<Ipv4Addr>() {
        Ok(_) => Authority::Address,
        Err(_) => Authority::Name(name),
    })
}

fn is_port(p: &str) -> bool {
    (1..=5).contains(&p.len()) && p.bytes().all(|b| b.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unspecified_bind_prints_the_machine_name_and_others_their_address() {
        let any4 = IpAddr::V4(Ipv4Addr::UNSPECIFIED);
        let any6 = IpAddr::V6(Ipv6Addr::UNSPECIFIED);
        assert_eq!(url_host(any4, Some("bigmachine")), "bigmachine");
        assert_eq!(url_host(any6, Some("bigmachine")), "bigmachine");
        assert_eq!(url_host(any4, None), "127.0.0.1");
        assert_eq!(url_host(any6, None), "[::1]");
        let lan: IpAddr = "192.168.1.5".parse().unwrap_or(any4);
        assert_eq!(url_host(lan, Some("bigmachine")), "192.168.1.5");
        assert_eq!(url_host(IpAddr::V6(Ipv6Addr::LOCALHOST), None), "[::1]");
    }

    #[test]
    fn host_names_are_letters_digits_and_hyphens_in_labels() {
        for good in ["bigmachine", "node-7", "a.b.example", "x1"] {
            assert!(is_host_name(good), "{good}");
        }
        for bad in [
            "",
            "-a",
            "a-",
            "a..b",
            "has space",
            "ünï",
            "10.0.0.1",
            "a_b",
            "a/b",
        ] {
            assert!(!is_host_name(bad), "{bad}");
        }
        assert!(!is_host_name(&"a".repeat(64)));
    }

    #[test]
    fn the_printed_name_loopback_names_and_addresses_are_allowed_and_nothing_else() {
        let hosts = Hosts::new("BigMachine");
        for ok in [
            "bigmachine:8800",
            "BIGMACHINE",
            "bigmachine.:8800",
            "localhost:9000",
            "127.0.0.1:8800",
            "10.1.2.3",
            "[::1]:8800",
            "[fe80::1]",
        ] {
            assert!(hosts.allows(ok), "{ok}");
        }
        for refused in [
            "evil.example:8800",
            "bigmachine.evil.example:8800",
            "evilbigmachine",
            "bigmachine:port",
            "bigmachine:8800:1",
            ":8800",
            "",
            "[::1",
            "[nothost]:8800",
            "[::1]8800",
            "localhost.evil.example",
        ] {
            assert!(!hosts.allows(refused), "{refused}");
        }
        // A loopback server answers to its address and localhost, no other name.
        let local = Hosts::new("127.0.0.1");
        assert!(local.allows("127.0.0.1:1") && local.allows("localhost:1"));
        assert!(!local.allows("bigmachine:1"));
    }
}
