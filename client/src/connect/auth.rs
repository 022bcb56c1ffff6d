//! The bearer token sent with every call.

use tonic::metadata::{AsciiMetadataValue, MetadataValue};
use tonic::service::Interceptor;
use tonic::{Request, Status};

/// Adds `authorization: Bearer <token>` to every request when a token is given, and
/// leaves requests untouched otherwise.
#[derive(Clone, Debug, Default)]
pub struct BearerAuth {
    header: Option<AsciiMetadataValue>,
}

/// A token that cannot be carried in an HTTP header.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the bearer token cannot be sent in an HTTP header (visible ASCII only)")]
pub struct InvalidToken;

impl BearerAuth {
    /// An interceptor sending `token`, or nothing for `None`.
    pub fn new(token: Option<&str>) -> Result<Self, InvalidToken> {
        let header = token
            .map(|t| MetadataValue::try_from(format!("Bearer {t}")).map_err(|_| InvalidToken))
            .transpose()?;
        Ok(BearerAuth { header })
    }
}

impl Interceptor for BearerAuth {
    fn call(&mut self, mut request: Request<()>) -> Result<Request<()>, Status> {
        if let Some(value) = &self.header {
            request
                .metadata_mut()
                .insert("authorization", value.clone());
        }
        Ok(request)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn bearer_auth_adds_the_header_when_a_token_is_given() {
        let mut auth = BearerAuth::new(Some("s3cret")).unwrap();
        let request = auth.call(Request::new(())).unwrap();
        let value = request.metadata().get("authorization").unwrap();
        assert_eq!(value.to_str().unwrap(), "Bearer s3cret");
    }

    #[test]
    fn bearer_auth_without_token_adds_nothing() {
        let mut auth = BearerAuth::new(None).unwrap();
        let request = auth.call(Request::new(())).unwrap();
        assert!(request.metadata().get("authorization").is_none());
    }

    #[test]
    fn a_token_with_a_newline_is_refused() {
        assert_eq!(BearerAuth::new(Some("a\nb")).unwrap_err(), InvalidToken);
    }
}
