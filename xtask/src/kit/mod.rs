//! What every archive carries beside its description and binaries, so that a user can check an
//! importer against it: the documentation page (`documentation/index.html`) and the reference
//! results of FMI-LS-REF ([`reference`]).

mod reference;

use crate::documentation;
use crate::fmu::Standard;

/// One file of an archive: its name in the archive and its bytes.
pub struct Entry {
    pub name: String,
    pub bytes: Vec<u8>,
}

/// The kit's files in the archive of model `id` for `standard`, whose description is `xml`.
pub fn entries(standard: &Standard, id: &str, xml: &str) -> Result<Vec<Entry>, String> {
    let _ = standard;
    let mut kit = vec![Entry {
        name: "documentation/index.html".into(),
        bytes: documentation::render(id, xml)?.into_bytes(),
    }];
    kit.extend(reference::entries(id)?);
    Ok(kit)
}
