use super::*;

#[test]
fn the_root_is_the_console_page() {
    let r = lookup(&Method::GET, "/");
    assert_eq!(r.status(), StatusCode::OK);
    assert_eq!(
        r.headers()[header::CONTENT_TYPE],
        "text/html; charset=utf-8"
    );
    assert_eq!(r.headers()[header::CACHE_CONTROL], "no-cache");
    let index = Assets::get("index.html").expect("index.html is embedded");
    let text = String::from_utf8_lossy(&index.data);
    assert!(text.contains("<script"), "index.html loads the bundle");
}

#[test]
fn every_script_the_page_names_is_served() {
    let index = Assets::get("index.html").unwrap();
    let text = String::from_utf8_lossy(&index.data).into_owned();
    let mut found = 0;
    for part in text.split("src=\"").skip(1) {
        let path = &part[..part.find('"').unwrap()];
        let r = lookup(&Method::GET, path);
        assert_eq!(r.status(), StatusCode::OK, "{path}");
        assert_eq!(
            r.headers()[header::CONTENT_TYPE],
            "text/javascript; charset=utf-8",
            "{path}"
        );
        found += 1;
    }
    assert!(found >= 1);
}

#[test]
fn unknown_paths_and_other_methods_are_refused() {
    assert_eq!(
        lookup(&Method::GET, "/nothing-here").status(),
        StatusCode::NOT_FOUND
    );
    assert_eq!(
        lookup(&Method::GET, "/../Cargo.toml").status(),
        StatusCode::NOT_FOUND
    );
    let post = lookup(&Method::POST, "/");
    assert_eq!(post.status(), StatusCode::METHOD_NOT_ALLOWED);
    assert_eq!(post.headers()[header::ALLOW], "GET, HEAD");
    // The stamp of the bundle's inputs is not an asset.
    assert_eq!(
        lookup(&Method::GET, "/bundle-hash.txt").status(),
        StatusCode::NOT_FOUND
    );
}

#[test]
fn a_head_states_the_length_its_get_sends() {
    let index = Assets::get("index.html").unwrap();
    for method in [Method::GET, Method::HEAD] {
        let r = lookup(&method, "/");
        assert_eq!(
            r.headers()[header::CONTENT_LENGTH],
            index.data.len().to_string(),
            "{method}"
        );
    }
}

#[tokio::test]
async fn a_call_to_no_service_is_unimplemented_in_its_own_content_type() {
    for content_type in [
        "application/grpc",
        "application/grpc-web+proto",
        "application/grpc-web-text",
    ] {
        let request = Request::builder()
            .method(Method::POST)
            .uri("/laparo.v1.Nope/X")
            .header(header::CONTENT_TYPE, content_type)
            .body(Body::empty())
            .unwrap();
        let r = asset(request).await;
        assert_eq!(r.headers()[header::CONTENT_TYPE], content_type);
        assert_eq!(r.headers()["grpc-status"], "12", "{content_type}");
    }
}
