//! Reads what the cross test's host printed (tests/cross/host.c) and compares two platforms.

/// Largest relative difference two platforms may show in any output.
pub const TOLERANCE: f64 = 1e-12;

/// The outputs after step `k`, or at the instant inside step `k` where fmi3DoStep returned early
/// (`early`, its lastSuccessfulTime), each mesh's contact mode, and the contact switches counted
/// so far.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    pub k: u64,
    pub early: Option<f64>,
    /// The meshes' contact modes as the host printed them (`1`, or `1,-1` for two meshes).
    pub contact: String,
    pub switches: u64,
    /// The Real outputs the host was given, in their order.
    pub values: Vec<f64>,
}

impl Sample {
    /// Where the sample was taken, in messages.
    fn at(&self) -> String {
        match self.early {
            Some(_) => format!("at the early return in step {}", self.k),
            None => format!("after step {}", self.k),
        }
    }
}

/// The host's `@ <kind> ...` lines of the given kinds, in their order, as fields from the kind on
/// (Windows' programs end lines in \r\n).
fn records<'a>(output: &'a str, kinds: &[&str]) -> Vec<Vec<&'a str>> {
    output
        .lines()
        .filter_map(|line| {
            let mut fields = line.trim_end_matches('\r').split_whitespace();
            let fields: Vec<&str> = (fields.next() == Some("@")).then(|| fields.collect())?;
            fields
                .first()
                .is_some_and(|kind| kinds.contains(kind))
                .then_some(fields)
        })
        .collect()
}

/// The `@ sample` lines and, in their place among them, the `@ early` lines (the same fields
/// with the instant of the early return before the outputs).
pub fn samples(output: &str) -> Result<Vec<Sample>, String> {
    let samples = records(output, &["sample", "early"])
        .into_iter()
        .map(|fields| {
            let bad = || format!("malformed sample line: @ {}", fields.join(" "));
            let hex = |field: &str| u64::from_str_radix(field, 16).map(f64::from_bits).map_err(|_| bad());
            let (early, outputs) = match fields[0] {
                "early" if fields.len() > 5 => (Some(hex(fields[4])?), &fields[5..]),
                "sample" if fields.len() > 4 => (None, &fields[4..]),
                _ => return Err(bad()),
            };
            let values = outputs.iter().map(|field| hex(field)).collect::<Result<Vec<_>, _>>()?;
            let contact = fields[2];
            if contact.split(',').any(|mode| mode.parse::<i32>().is_err()) {
                return Err(bad());
            }
            Ok(Sample {
                k: fields[1].parse().map_err(|_| bad())?,
                early,
                contact: contact.to_string(),
                switches: fields[3].parse().map_err(|_| bad())?,
                values,
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    if samples.is_empty() {
        return Err("the host printed no sample".into());
    }
    Ok(samples)
}

/// `(case, status, messages logged)` of each misuse line.
pub fn misuse(output: &str) -> Result<Vec<(String, String, String)>, String> {
    let cases: Vec<_> = records(output, &["misuse"])
        .into_iter()
        .map(|f| match f.as_slice() {
            [_, case, status, logged] => Ok((case.to_string(), status.to_string(), logged.to_string())),
            _ => Err(format!("malformed misuse line: @ {}", f.join(" "))),
        })
        .collect::<Result<_, _>>()?;
    if cases.is_empty() {
        return Err("the host printed no misuse case".into());
    }
    Ok(cases)
}

/// |a − b| relative to the larger magnitude; 0 when both are the same number (0 and −0 too).
pub fn relative_difference(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else if a.is_nan() || b.is_nan() {
        f64::INFINITY
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

/// How far one platform's samples are from the reference platform's.
#[derive(Debug, PartialEq)]
pub struct Agreement {
    pub samples: usize,
    /// Samples whose every output has the same bits on both platforms.
    pub bit_identical: usize,
    pub max_relative: f64,
    /// Output and sample (see [`Sample::at`]) of the largest difference.
    pub worst: Option<(String, String)>,
}

/// Same steps and early returns, same contact modes and switch counts, and every output (named
/// by `outputs`, in the samples' order) and early-return instant within [`TOLERANCE`].
pub fn agree(reference: &[Sample], other: &[Sample], outputs: &[String]) -> Result<Agreement, String> {
    if reference.len() != other.len() {
        return Err(format!(
            "{} samples against {} of the reference",
            other.len(),
            reference.len()
        ));
    }
    let mut agreement = Agreement {
        samples: reference.len(),
        bit_identical: 0,
        max_relative: 0.0,
        worst: None,
    };
    for (r, o) in reference.iter().zip(other) {
        if (r.k, r.early.is_some()) != (o.k, o.early.is_some()) {
            return Err(format!("a sample {} where the reference has one {}", o.at(), r.at()));
        }
        if r.values.len() != outputs.len() || o.values.len() != outputs.len() {
            return Err(format!(
                "{} outputs {}, the reference {}, the model {}",
                o.values.len(),
                o.at(),
                r.values.len(),
                outputs.len()
            ));
        }
        if (&r.contact, r.switches) != (&o.contact, o.switches) {
            return Err(format!(
                "{}: contact {} after {} switches, the reference contact {} after {}",
                r.at(),
                o.contact,
                o.switches,
                r.contact,
                r.switches
            ));
        }
        let early = r.early.zip(o.early).map(|(a, b)| ("lastSuccessfulTime", (a, b)));
        let values = outputs
            .iter()
            .map(String::as_str)
            .zip(r.values.iter().copied().zip(o.values.iter().copied()));
        let compared: Vec<(&str, (f64, f64))> = early.into_iter().chain(values).collect();
        if compared.iter().all(|(_, (a, b))| a.to_bits() == b.to_bits()) {
            agreement.bit_identical += 1;
        }
        for (name, (a, b)) in compared {
            let d = relative_difference(a, b);
            if d > agreement.max_relative {
                agreement.max_relative = d;
                agreement.worst = Some((name.to_string(), r.at()));
            }
        }
    }
    if agreement.max_relative > TOLERANCE {
        let (name, at) = agreement.worst.expect("a difference names its output");
        return Err(format!(
            "{name} {at} differs by {:e} (relative) from the reference, over {TOLERANCE:e}",
            agreement.max_relative
        ));
    }
    Ok(agreement)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(k: u64, contact: &str, switches: u64, values: &[f64]) -> String {
        let hex: Vec<String> = values.iter().map(|v| format!("{:016x}", v.to_bits())).collect();
        format!("@ sample {k} {contact} {switches} {}\r\n", hex.join(" "))
    }

    /// A model's outputs as the host samples them: its description's Real outputs.
    fn outputs_of(id: &str) -> Vec<String> {
        let xml = (crate::fmu::STANDARDS[0].description)(id);
        let doc = roxmltree::Document::parse(&xml).unwrap();
        super::super::sampled(&doc)
            .0
            .into_iter()
            .map(|(name, _)| name.to_string())
            .collect()
    }

    fn shaft() -> Vec<String> {
        outputs_of("BacklashShaft")
    }

    #[test]
    fn samples_are_read_bit_for_bit_from_either_line_ending() {
        let values = [0.1, -2.5, 1e-300, f64::MIN_POSITIVE, -0.0, 3.0, 1.0 / 3.0];
        let text = format!("noise\n{}@ misuse x 3 1\n", line(100, "-1", 4, &values));
        let parsed = samples(&text).unwrap();
        assert_eq!(parsed.len(), 1);
        assert_eq!(
            (parsed[0].k, parsed[0].contact.as_str(), parsed[0].switches),
            (100, "-1", 4)
        );
        for (a, b) in parsed[0].values.iter().zip(&values) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
        assert!(samples("@ sample 1 0 0\n").is_err(), "a sample without outputs");
        assert!(
            samples("@ sample 1 1,x 0 3ff0000000000000\n").is_err(),
            "a contact mode that is no number"
        );
        assert!(samples("nothing here\n").is_err());
        assert_eq!(misuse(&text).unwrap(), [("x".into(), "3".into(), "1".into())]);
    }

    #[test]
    fn platforms_disagree_beyond_the_tolerance_or_in_a_contact_switch() {
        let outputs = shaft();
        let base = Sample {
            k: 10,
            early: None,
            contact: "1".into(),
            switches: 2,
            values: vec![1.0; 7],
        };
        let reference = std::slice::from_ref(&base);
        let same = agree(reference, reference, &outputs).unwrap();
        assert_eq!((same.bit_identical, same.max_relative), (1, 0.0));

        let mut close = base.clone();
        close.values[3] = 1.0 + 4.0 * f64::EPSILON;
        let near = agree(reference, &[close], &outputs).unwrap();
        assert_eq!(near.bit_identical, 0);
        assert_eq!(near.worst, Some(("omega_L".into(), "after step 10".into())));
        assert!(near.max_relative > 0.0 && near.max_relative <= TOLERANCE);

        let mut far = base.clone();
        far.values[5] = 1.0 + 1e-9;
        assert!(agree(reference, &[far], &outputs)
            .unwrap_err()
            .contains("bound after step 10"));

        let mut nan = base.clone();
        nan.values[0] = f64::NAN;
        assert!(agree(reference, &[nan], &outputs).is_err());

        let mut switched = base.clone();
        switched.switches = 3;
        assert!(agree(reference, &[switched], &outputs).is_err());
        assert!(agree(reference, &[], &outputs).is_err());
    }

    #[test]
    fn early_returns_are_read_in_place_and_compared_by_their_instant() {
        let outputs = shaft();
        let values = [0.5_f64; 7];
        let early = |t: f64| {
            let hex: Vec<String> = values.iter().map(|v| format!("{:016x}", v.to_bits())).collect();
            format!("@ early 7 0 1 {:016x} {}\n", t.to_bits(), hex.join(" "))
        };
        let text = format!("{}{}", early(6.5e-3), line(7, "0", 1, &values));
        let reference = samples(&text).unwrap();
        assert_eq!(
            reference.iter().map(|s| s.early).collect::<Vec<_>>(),
            [Some(6.5e-3), None]
        );
        assert_eq!(agree(&reference, &reference, &outputs).unwrap().bit_identical, 2);

        let moved = samples(&format!("{}{}", early(6.5e-3 * (1.0 + 1e-9)), line(7, "0", 1, &values))).unwrap();
        let error = agree(&reference, &moved, &outputs).unwrap_err();
        assert!(
            error.contains("lastSuccessfulTime at the early return in step 7"),
            "{error}"
        );

        let missing = samples(&format!("{}{}", line(7, "0", 1, &values), line(7, "0", 1, &values))).unwrap();
        assert!(agree(&reference, &missing, &outputs).is_err());
        assert!(samples("@ early 7 0 1 3ff0000000000000\n").is_err());
    }

    #[test]
    fn a_gearboxs_samples_carry_each_meshs_contact_and_its_own_outputs() {
        let outputs = outputs_of("BacklashTwoStage");
        let mut values = vec![1.0; outputs.len()];
        let reference = samples(&line(5, "1,-1", 3, &values)).unwrap();
        assert_eq!(reference[0].contact, "1,-1");
        assert_eq!(agree(&reference, &reference, &outputs).unwrap().bit_identical, 1);

        // One mesh in another mode is a disagreement, whatever the other does.
        let other_mesh = samples(&line(5, "1,0", 3, &values)).unwrap();
        assert!(agree(&reference, &other_mesh, &outputs)
            .unwrap_err()
            .contains("contact 1,0"));

        values[outputs.iter().position(|n| n == "psi_2").unwrap()] = 1.0 + 1e-9;
        let error = agree(&reference, &samples(&line(5, "1,-1", 3, &values)).unwrap(), &outputs).unwrap_err();
        assert!(error.contains("psi_2 after step 5"), "{error}");

        // Samples are compared in the model's outputs only: a sample of another length is refused.
        let short = samples(&line(5, "1,-1", 3, &values[..outputs.len() - 1])).unwrap();
        assert!(agree(&short, &short, &outputs).is_err());
    }

    #[test]
    fn relative_difference_of_equal_numbers_and_of_signed_zeros_is_zero() {
        assert_eq!(relative_difference(0.0, -0.0), 0.0);
        assert_eq!(relative_difference(2.0, 1.0), 0.5);
        assert!(relative_difference(0.0, 1e-300) == 1.0);
    }
}
