//! Images: linear-light RGB in memory, sRGB 8-bit on disk (PNG, animated GIF), and PSNR.
//! Files are written atomically: complete, or the previous file stays.

use crate::colorspace::linear_to_srgb;
use crate::error::{RenderError, Result};
use std::path::Path;
use tetloc_io::output::{write_atomically, AtomicFile};

#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// Linear RGB, row-major, top row first.
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// sRGB-encoded 8-bit RGB bytes.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels.iter().flat_map(|p| p.map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)).collect()
    }

    pub fn write_png(&self, path: &Path) -> Result<()> {
        write_atomically(path, |file| {
            let mut enc = png::Encoder::new(file, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
            let encode = |e: png::EncodingError| RenderError::file(path, format!("cannot write PNG: {e}"));
            let mut w = enc.write_header().map_err(encode)?;
            w.write_image_data(&self.to_srgb8()).map_err(encode)?;
            w.finish().map_err(encode)
        })
    }
}

/// A looping animated GIF written frame by frame, so long orbits need no memory per frame.
pub struct GifWriter {
    enc: gif::Encoder<AtomicFile>,
    path: std::path::PathBuf,
    size: (u16, u16),
    delay_cs: u16,
}

impl GifWriter {
    /// Starts `path` for frames of `width`×`height`, shown `delay_cs` hundredths of a second each.
    pub fn create(path: &Path, width: u32, height: u32, delay_cs: u16) -> Result<GifWriter> {
        let (Ok(w), Ok(h)) = (u16::try_from(width), u16::try_from(height)) else {
            return Err(RenderError::file(
                path,
                format!("GIF images are at most 65535 pixels a side, not {width}x{height}"),
            ));
        };
        let file = AtomicFile::create(path)?;
        let encode = |e: gif::EncodingError| RenderError::file(path, format!("cannot write GIF: {e}"));
        let mut enc = gif::Encoder::new(file, w, h, &[]).map_err(encode)?;
        enc.set_repeat(gif::Repeat::Infinite).map_err(encode)?;
        Ok(GifWriter { enc, path: path.to_path_buf(), size: (w, h), delay_cs })
    }

    pub fn add(&mut self, img: &Image) -> Result<()> {
        if (img.width, img.height) != (self.size.0 as u32, self.size.1 as u32) {
            return Err(RenderError::Invalid(format!(
                "a {}x{} frame for a {}x{} GIF",
                img.width, img.height, self.size.0, self.size.1
            )));
        }
        // NeuQuant palette per frame; speed 10 is gif's balance of quality and time.
        let mut frame = gif::Frame::from_rgb_speed(self.size.0, self.size.1, &img.to_srgb8(), 10);
        frame.delay = self.delay_cs;
        self.enc.write_frame(&frame).map_err(|e| RenderError::file(&self.path, format!("cannot write GIF: {e}")))
    }

    /// Writes the trailer and flushes the file.
    /// Ends the GIF and puts it in place (dropped unfinished, the previous file stays).
    pub fn finish(self) -> Result<()> {
        let path = self.path;
        let w = self.enc.into_inner().map_err(|e| RenderError::io(&path, e))?;
        Ok(w.commit()?)
    }
}

/// Peak signal-to-noise ratio in dB between two images' 8-bit sRGB encodings (infinite for
/// identical images).
pub fn psnr(a: &Image, b: &Image) -> Result<f64> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(RenderError::Invalid(format!(
            "PSNR of a {}x{} and a {}x{} image",
            a.width, a.height, b.width, b.height
        )));
    }
    let (x, y) = (a.to_srgb8(), b.to_srgb8());
    let mse = x.iter().zip(&y).map(|(&p, &q)| (p as f64 - q as f64).powi(2)).sum::<f64>() / x.len() as f64;
    Ok(if mse == 0.0 { f64::INFINITY } else { 10.0 * (255.0f64 * 255.0 / mse).log10() })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(w: u32, h: u32, c: f32) -> Image {
        Image { width: w, height: h, pixels: vec![[c; 3]; (w * h) as usize] }
    }

    #[test]
    fn psnr_of_known_errors() {
        let a = flat(4, 4, 0.0);
        assert_eq!(psnr(&a, &a).unwrap(), f64::INFINITY);
        // Every byte off by one level: MSE 1, PSNR = 20·log10(255).
        let b = Image { pixels: vec![[crate::colorspace::srgb_to_linear(1.0 / 255.0); 3]; 16], ..a.clone() };
        assert!((psnr(&a, &b).unwrap() - 48.1308).abs() < 1e-3);
        assert!(psnr(&a, &flat(2, 8, 0.0)).is_err());
    }

    #[test]
    fn png_and_gif_round_trip() {
        use std::fs::File;
        let dir = std::env::temp_dir().join(format!("tetloc-render-img-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut img = flat(3, 2, 0.5);
        img.pixels[0] = [1.0, 0.0, 0.0];
        let p = dir.join("a.png");
        img.write_png(&p).unwrap();
        let dec = png::Decoder::new(File::open(&p).unwrap());
        let mut r = dec.read_info().unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        let info = r.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (3, 2));
        assert_eq!(&buf[..info.buffer_size()], &img.to_srgb8()[..]);
        assert_eq!(buf[0..3], [255, 0, 0]);
        assert_eq!(buf[3], 188, "linear 0.5 is sRGB 188");

        let g = dir.join("a.gif");
        let mut w = GifWriter::create(&g, 3, 2, 4).unwrap();
        w.add(&img).unwrap();
        w.add(&flat(3, 2, 1.0)).unwrap();
        assert!(w.add(&flat(2, 3, 1.0)).is_err(), "frames must match the GIF's size");
        w.finish().unwrap();
        let mut d = gif::DecodeOptions::new().read_info(File::open(&g).unwrap()).unwrap();
        let mut n = 0;
        while d.read_next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, 2);
        let e = img.write_png(&dir.join("no/such/dir/x.png")).unwrap_err().to_string();
        assert!(e.contains("no/such/dir/x.png"), "{e}");
        // A GIF dropped unfinished leaves the previous file, and no other.
        let mut w = GifWriter::create(&g, 3, 2, 4).unwrap();
        w.add(&img).unwrap();
        drop(w);
        let mut d = gif::DecodeOptions::new().read_info(File::open(&g).unwrap()).unwrap();
        let mut n = 0;
        while d.read_next_frame().unwrap().is_some() {
            n += 1;
        }
        assert_eq!(n, 2, "the finished GIF of two frames is still there");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert!(names.iter().all(|n| !n.to_string_lossy().ends_with(".tmp")), "{names:?}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
