//! Byte- and line-level mutations of valid inputs (in the manner of AFL's havoc stage):
//! bit flips, interesting bytes and integers, insertions, deletions, duplicated or
//! swapped ranges and lines, truncation, and tokens of the format (a dictionary).

use super::rng::Rng;

/// Bytes that matter to the text formats (separators, signs, digits, quotes, YAML).
const INTERESTING_BYTES: &[u8] = b"\0\n\r\t ,.-+eE0919:#'\"{}[]|>&*!%@`\\/\x7f\xff\xc3";

/// Integers that matter to binary formats (lengths, counts, offsets), written as 1, 2, 4
/// or 8 bytes in either byte order.
const INTERESTING_INTS: &[u64] = &[
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    16,
    0x7f,
    0x80,
    0xff,
    0x100,
    0x7fff,
    0x8000,
    0xffff,
    0x1_0000,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
    0x1_0000_0000,
    0x7fff_ffff_ffff_ffff,
    0x8000_0000_0000_0000,
    u64::MAX,
];

/// Apply 1 to 8 random mutations to `data`, keeping it at most `max_len` bytes long.
/// `dictionary` holds tokens of the format, inserted or written over the data.
pub fn mutate(rng: &mut Rng, data: &mut Vec<u8>, dictionary: &[&[u8]], max_len: usize) {
    let rounds = 1 << rng.below(4);
    for _ in 0..rounds {
        mutate_once(rng, data, dictionary);
    }
    data.truncate(max_len);
}

fn mutate_once(rng: &mut Rng, data: &mut Vec<u8>, dictionary: &[&[u8]]) {
    let len = data.len();
    match rng.below(15) {
        // Flip one bit.
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        // Overwrite a byte with a random or an interesting one.
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = if rng.one_in(2) {
                rng.next_u64() as u8
            } else {
                *rng.pick(INTERESTING_BYTES)
            };
        }
        // Insert a few bytes.
        2 => {
            let i = rng.below(len + 1);
            let n = rng.range(1, 8);
            let bytes: Vec<u8> = (0..n)
                .map(|_| {
                    if rng.one_in(2) {
                        *rng.pick(INTERESTING_BYTES)
                    } else {
                        rng.next_u64() as u8
                    }
                })
                .collect();
            data.splice(i..i, bytes);
        }
        // Delete a range.
        3 if len > 0 => {
            let i = rng.below(len);
            let n = rng.range(1, (len - i).min(16));
            data.drain(i..i + n);
        }
        // Duplicate a range somewhere else.
        4 if len > 0 => {
            let i = rng.below(len);
            let n = rng.range(1, (len - i).min(64));
            let copy = data[i..i + n].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, copy);
        }
        // Write an interesting integer over the data.
        5 | 6 if len > 0 => {
            let width = *rng.pick(&[1usize, 2, 4, 8]);
            let v = *rng.pick(INTERESTING_INTS);
            let v = if rng.one_in(4) { v.wrapping_neg() } else { v };
            let bytes = if rng.one_in(2) {
                v.to_le_bytes()[..width].to_vec()
            } else {
                v.to_be_bytes()[8 - width..].to_vec()
            };
            let i = rng.below(len);
            let end = (i + width).min(len);
            data[i..end].copy_from_slice(&bytes[..end - i]);
        }
        // Add or subtract a small number from a byte (lengths off by one).
        7 if len > 0 => {
            let i = rng.below(len);
            let delta = rng.range(1, 16) as u8;
            data[i] = if rng.one_in(2) {
                data[i].wrapping_add(delta)
            } else {
                data[i].wrapping_sub(delta)
            };
        }
        // Insert or overwrite a dictionary token.
        8 | 9 if !dictionary.is_empty() => {
            let token = *rng.pick(dictionary);
            let i = rng.below(len + 1);
            if rng.one_in(2) || i == len {
                data.splice(i..i, token.iter().copied());
            } else {
                let end = (i + token.len()).min(len);
                data.splice(i..end, token.iter().copied());
            }
        }
        // Truncate.
        10 if len > 0 => data.truncate(rng.below(len)),
        // Line operations: duplicate, delete or swap whole lines.
        11..=13 => mutate_lines(rng, data),
        // Swap two ranges' bytes.
        _ if len > 1 => {
            let a = rng.below(len);
            let b = rng.below(len);
            data.swap(a, b);
        }
        _ => data.push(rng.next_u64() as u8),
    }
}

/// Duplicate, delete, swap or move lines (split on `\n`, kept with their terminators).
fn mutate_lines(rng: &mut Rng, data: &mut Vec<u8>) {
    let mut lines: Vec<Vec<u8>> = data
        .split_inclusive(|&b| b == b'\n')
        .map(<[u8]>::to_vec)
        .collect();
    if lines.is_empty() {
        return;
    }
    let n = lines.len();
    let (a, b) = (rng.below(n), rng.below(n));
    match rng.below(4) {
        0 => {
            let line = lines[a].clone();
            lines.insert(b, line);
        }
        1 => {
            lines.remove(a);
        }
        2 => lines.swap(a, b),
        _ => {
            // Re-indent a line (YAML structure).
            let line = &mut lines[a];
            let indent = line.iter().take_while(|&&c| c == b' ').count();
            line.drain(..indent);
            let spaces = rng.below(9);
            line.splice(0..0, std::iter::repeat_n(b' ', spaces));
        }
    }
    *data = lines.concat();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_change_the_data_and_respect_the_length_limit() {
        let mut rng = Rng::new(3);
        let seed = b"a,b,c\n1,2,3\n4,5,6\n".to_vec();
        let mut changed = 0;
        for _ in 0..1000 {
            let mut d = seed.clone();
            mutate(&mut rng, &mut d, &[b"nan", b"1e308"], 40);
            assert!(d.len() <= 40);
            changed += usize::from(d != seed);
        }
        assert!(changed > 900, "{changed}");
    }
}
