//! The page and its assets, compiled into the binary (no build step, no network): the only
//! things the server hands out. Paths are matched exactly, as sent (still percent-encoded), so
//! `..`, `%2e%2e` and the like name nothing and get 404.

/// The page; `{{TOKEN}}` stands for the server's token in the URLs of its assets.
const INDEX: &str = include_str!("../assets/index.html");

/// An asset: its bytes and media type.
pub struct Asset {
    /// The body.
    pub body: &'static str,
    /// The `Content-Type`.
    pub mime: &'static str,
}

/// The assets besides the page, by path.
const ASSETS: [(&str, Asset); 2] = [
    (
        "/app.js",
        Asset {
            body: include_str!("../assets/app.js"),
            mime: "text/javascript; charset=utf-8",
        },
    ),
    (
        "/style.css",
        Asset {
            body: include_str!("../assets/style.css"),
            mime: "text/css; charset=utf-8",
        },
    ),
];

/// The asset at exactly `path`, if there is one.
pub fn asset(path: &str) -> Option<&'static Asset> {
    ASSETS.iter().find(|(p, _)| *p == path).map(|(_, a)| a)
}

/// The page with `token` in its asset URLs.
pub fn index(token: &str) -> String {
    INDEX.replace("{{TOKEN}}", token)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_exact_paths_name_assets() {
        assert!(asset("/app.js").is_some());
        assert!(asset("/style.css").is_some());
        for p in [
            "/app.js/",
            "/./app.js",
            "/../app.js",
            "/%2e%2e/app.js",
            "/APP.JS",
            "app.js",
            "/assets/app.js",
        ] {
            assert!(asset(p).is_none(), "{p}");
        }
    }

    #[test]
    fn the_page_carries_the_token_to_its_assets() {
        let page = index("00ff");
        assert!(page.contains("app.js?token=00ff"));
        assert!(page.contains("style.css?token=00ff"));
        assert!(!page.contains("{{TOKEN}}"));
    }
}
