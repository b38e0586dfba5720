//! Signed policy updates: an ed25519 signature from the cloud's key over a policy's weights and
//! everything that says what they are and who they are for.
//!
//! A vehicle drives with weights received over the network only when they verify against the
//! key it trusts (edge/src/vehicle/push.rs). The signed message is
//!
//! ```text
//! DOMAIN ‖ len‖policy_id ‖ version (u32 BE) ‖ len‖algo ‖ len‖target ‖ len(weights) (u64 BE) ‖ SHA-512(weights)
//! ```
//!
//! with every string prefixed by its length (u32 BE), so no two field lists give one message,
//! and [`DOMAIN`] first, so a signature made for anything else (another message type, another
//! format version) never verifies as a policy update's. The weights enter as their SHA-512 (the
//! hash ed25519 itself uses): the cloud signs one update per vehicle, each naming its target,
//! without hashing 64 MiB of weights through ed25519 twice per vehicle. The header (sequence
//! number, clocks) is transport bookkeeping and not signed, so a recorded update can be sent
//! again and still verifies: the vehicle refuses any version of a policy id at or below the
//! highest it accepted of that id (even after driving another policy since), for as long as its
//! process runs; a restarted vehicle takes a replayed update again.
//!
//! Keys travel as text files (this module formats and parses them; the binary reads and writes
//! them): one line naming the kind, one line of 64 hex digits (the ed25519 seed of a signing key,
//! the point of a verifying key).

use ed25519_dalek::{Signature, Signer, SigningKey, VerifyingKey};
use risktwin_common::telemetry::PolicyUpdate;
use sha2::{Digest, Sha512};

/// Domain separation of the signed message (see the module doc); a new layout gets a new one.
pub const DOMAIN: &[u8] = b"risktwin.v1.PolicyUpdate ed25519 signature, layout 1\0";
/// First line of a signing-key file.
pub const SIGNING_KEY_HEADER: &str = "risktwin policy signing key (ed25519 seed, hex)";
/// First line of a verifying-key file.
pub const VERIFYING_KEY_HEADER: &str = "risktwin policy verifying key (ed25519, hex)";

/// What is wrong with a key file's text or a signature.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SignatureError {
    #[error("the first line is {found:?}, not {expected:?}")]
    WrongHeader { found: String, expected: &'static str },
    #[error("the key line is not 64 hex digits ({found} characters)")]
    BadKeyText { found: usize },
    #[error("the key is not a valid ed25519 public key")]
    BadPoint,
    #[error("the key is a small-order (weak) ed25519 point, under which forged signatures verify")]
    WeakKey,
    #[error("the update carries no signature")]
    Unsigned,
    #[error("the signature is {found} bytes, not 64")]
    BadLength { found: usize },
    #[error("the signature does not verify against the trusted key")]
    Mismatch,
}

/// The cloud's key: signs policy updates.
#[derive(Clone)]
pub struct PolicySigningKey(SigningKey);

/// A key a vehicle trusts: verifies policy updates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolicyVerifyingKey(VerifyingKey);

impl std::fmt::Debug for PolicySigningKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // Never the secret; the public half names it.
        write!(f, "PolicySigningKey({})", hex(self.0.verifying_key().as_bytes()))
    }
}

/// The message an update's signature covers (see the module doc).
pub fn signed_message(u: &PolicyUpdate) -> Vec<u8> {
    let mut m = Vec::with_capacity(DOMAIN.len() + 128 + u.policy_id.len() + u.algo.len() + u.target.len());
    m.extend_from_slice(DOMAIN);
    let text = |m: &mut Vec<u8>, s: &str| {
        m.extend_from_slice(&(s.len() as u32).to_be_bytes());
        m.extend_from_slice(s.as_bytes());
    };
    text(&mut m, &u.policy_id);
    m.extend_from_slice(&u.version.to_be_bytes());
    text(&mut m, &u.algo);
    text(&mut m, &u.target);
    m.extend_from_slice(&(u.weights.len() as u64).to_be_bytes());
    m.extend_from_slice(&Sha512::digest(&u.weights));
    m
}

impl PolicySigningKey {
    /// The key of a 32-byte seed (from the OS's random source, or a key file).
    pub fn from_seed(seed: [u8; 32]) -> Self {
        Self(SigningKey::from_bytes(&seed))
    }

    /// The public half, for the vehicles to trust.
    pub fn verifying_key(&self) -> PolicyVerifyingKey {
        PolicyVerifyingKey(self.0.verifying_key())
    }

    /// Signs `update` as it stands (its target set): fills its `signature`.
    pub fn sign(&self, update: &mut PolicyUpdate) {
        update.signature = self.0.sign(&signed_message(update)).to_bytes().to_vec();
    }

    /// The key file's text.
    pub fn to_text(&self) -> String {
        format!("{SIGNING_KEY_HEADER}\n{}\n", hex(self.0.as_bytes()))
    }

    /// A key file's text back as a key.
    pub fn from_text(text: &str) -> Result<Self, SignatureError> {
        Ok(Self::from_seed(key_line(text, SIGNING_KEY_HEADER)?))
    }
}

impl PolicyVerifyingKey {
    /// Whether `update`'s signature is this key's over its weights and metadata.
    pub fn verify(&self, update: &PolicyUpdate) -> Result<(), SignatureError> {
        if update.signature.is_empty() {
            return Err(SignatureError::Unsigned);
        }
        let bytes: [u8; 64] = update
            .signature
            .as_slice()
            .try_into()
            .map_err(|_| SignatureError::BadLength { found: update.signature.len() })?;
        // Strict: no small-order key or R, canonical s (RFC 8032 §5.1.7 plus the checks that
        // keep a signature from verifying under more than one message or key).
        self.0
            .verify_strict(&signed_message(update), &Signature::from_bytes(&bytes))
            .map_err(|_| SignatureError::Mismatch)
    }

    /// The key file's text.
    pub fn to_text(&self) -> String {
        format!("{VERIFYING_KEY_HEADER}\n{}\n", hex(self.0.as_bytes()))
    }

    /// A key file's text back as a key.
    pub fn from_text(text: &str) -> Result<Self, SignatureError> {
        let bytes = key_line(text, VERIFYING_KEY_HEADER)?;
        let key = VerifyingKey::from_bytes(&bytes).map_err(|_| SignatureError::BadPoint)?;
        if key.is_weak() {
            return Err(SignatureError::WeakKey);
        }
        Ok(Self(key))
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The 32 bytes of a key file whose first line is `header`.
fn key_line(text: &str, header: &'static str) -> Result<[u8; 32], SignatureError> {
    let mut lines = text.lines();
    let first = lines.next().unwrap_or_default().trim();
    if first != header {
        return Err(SignatureError::WrongHeader { found: first.chars().take(80).collect(), expected: header });
    }
    let key = lines.next().unwrap_or_default().trim();
    let bad = || SignatureError::BadKeyText { found: key.chars().count() };
    // Hex digits only: `from_str_radix` alone would take a sign ("+f").
    if key.len() != 64 || !key.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(bad());
    }
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&key[2 * i..2 * i + 2], 16).map_err(|_| bad())?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::telemetry::{Frame, Header};

    fn update() -> PolicyUpdate {
        PolicyUpdate {
            header: Header {
                source: "cloud".into(),
                seq: 3,
                capture_time_ns: 1,
                publish_time_ns: 2,
                frame: Frame::World,
            },
            policy_id: "ppo-1".into(),
            version: 7,
            algo: "ppo".into(),
            weights: (0..=255).collect(),
            target: "site0/veh-1".into(),
            signature: Vec::new(),
        }
    }

    fn key(n: u8) -> PolicySigningKey {
        PolicySigningKey::from_seed([n; 32])
    }

    #[test]
    fn a_signed_update_verifies_and_the_header_is_not_signed() {
        let mut u = update();
        key(1).sign(&mut u);
        assert_eq!(u.signature.len(), 64);
        assert_eq!(key(1).verifying_key().verify(&u), Ok(()));
        u.header.seq = 99;
        assert_eq!(key(1).verifying_key().verify(&u), Ok(()));
    }

    #[test]
    fn changing_any_signed_field_breaks_the_signature() {
        let mut signed = update();
        key(1).sign(&mut signed);
        type Tamper = fn(&mut PolicyUpdate);
        let tampered: [(&str, Tamper); 7] = [
            ("a weights byte", |u| u.weights[17] ^= 1),
            ("a weights byte more", |u| u.weights.push(0)),
            ("policy_id", |u| u.policy_id = "ppo-2".into()),
            ("version", |u| u.version += 1),
            ("algo", |u| u.algo = "sac".into()),
            ("target", |u| u.target = "site0/veh-2".into()),
            ("the signature", |u| u.signature[0] ^= 0x80),
        ];
        for (what, tamper) in tampered {
            let mut u = signed.clone();
            tamper(&mut u);
            assert_eq!(key(1).verifying_key().verify(&u), Err(SignatureError::Mismatch), "{what}");
        }
    }

    #[test]
    fn fields_cannot_trade_bytes() {
        // "ab" + "c" and "a" + "bc" as policy id and algo are different messages.
        let (mut a, mut b) = (update(), update());
        (a.policy_id, a.algo) = ("ab".into(), "c".into());
        (b.policy_id, b.algo) = ("a".into(), "bc".into());
        assert_ne!(signed_message(&a), signed_message(&b));
        key(1).sign(&mut a);
        b.signature = a.signature.clone();
        assert_eq!(key(1).verifying_key().verify(&b), Err(SignatureError::Mismatch));
    }

    #[test]
    fn another_key_unsigned_and_short_signatures_are_refused() {
        let mut u = update();
        assert_eq!(key(1).verifying_key().verify(&u), Err(SignatureError::Unsigned));
        key(2).sign(&mut u);
        assert_eq!(key(1).verifying_key().verify(&u), Err(SignatureError::Mismatch));
        u.signature.truncate(63);
        assert_eq!(key(2).verifying_key().verify(&u), Err(SignatureError::BadLength { found: 63 }));
    }

    #[test]
    fn small_order_trust_keys_are_refused_and_never_verify() {
        // All zeros (a point of order 4) and the identity: valid encodings, weak keys.
        let identity = format!("01{}", "0".repeat(62));
        for point in ["0".repeat(64), identity] {
            let text = format!("{VERIFYING_KEY_HEADER}\n{point}\n");
            assert_eq!(PolicyVerifyingKey::from_text(&text), Err(SignatureError::WeakKey), "{point}");
        }
        // Under the identity key, R = identity and s = 0 pass the plain ed25519 equation for any
        // message; the strict check refuses it.
        let mut identity = [0u8; 32];
        identity[0] = 1;
        let weak = PolicyVerifyingKey(VerifyingKey::from_bytes(&identity).expect("the identity point"));
        let mut u = update();
        u.signature = [1].into_iter().chain([0; 63]).collect();
        assert_eq!(weak.verify(&u), Err(SignatureError::Mismatch));
    }

    #[test]
    fn key_files_round_trip_and_bad_ones_are_named() {
        let k = key(5);
        let back = PolicySigningKey::from_text(&k.to_text()).expect("signing key");
        assert_eq!(back.verifying_key(), k.verifying_key());
        let public = PolicyVerifyingKey::from_text(&k.verifying_key().to_text()).expect("verifying key");
        assert_eq!(public, k.verifying_key());
        // A signing key where a verifying key is expected, and the reverse.
        assert!(matches!(PolicyVerifyingKey::from_text(&k.to_text()), Err(SignatureError::WrongHeader { .. })));
        assert!(matches!(PolicySigningKey::from_text(&public.to_text()), Err(SignatureError::WrongHeader { .. })));
        let short = format!("{VERIFYING_KEY_HEADER}\nabcd\n");
        assert_eq!(PolicyVerifyingKey::from_text(&short), Err(SignatureError::BadKeyText { found: 4 }));
        let not_hex = format!("{SIGNING_KEY_HEADER}\n{}\n", "zz".repeat(32));
        assert_eq!(PolicySigningKey::from_text(&not_hex).unwrap_err(), SignatureError::BadKeyText { found: 64 });
        assert!(PolicySigningKey::from_text("").is_err());
        let signed = format!("{SIGNING_KEY_HEADER}\n{}\n", "+f".repeat(32));
        assert_eq!(PolicySigningKey::from_text(&signed).unwrap_err(), SignatureError::BadKeyText { found: 64 });
        assert!(!format!("{k:?}").contains(&hex(&[5; 32])), "Debug shows no secret");
    }
}
