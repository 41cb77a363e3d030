//! What every archive carries beside its description and binaries, so that a user can check an
//! importer against it: the documentation page (`documentation/index.html`), the reference
//! results of FMI-LS-REF ([`reference`]), and the model's icon with, in FMI 3.0, a plant's two
//! flanges as terminals ([`icon`]).

mod icon;
mod image;
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
    let mut kit = vec![Entry {
        name: "documentation/index.html".into(),
        bytes: documentation::render(id, xml)?.into_bytes(),
    }];
    kit.extend(reference::entries(id)?);
    kit.extend(icon::entries(standard.fmi_version, id, xml)?);
    Ok(kit)
}
