//! Contact sheets (`--contact-sheet FILE.png`): a labelled grid of thumbnails, one cell per
//! view of `render --views`/`--turntable` or per job of `batch`.
//!
//! Layout, all in pixels: a [`PADDING`] border around and between the cells; each cell is a
//! thumbnail box (`cell_width` wide, as tall as the images' aspect asks) over a label strip
//! [`LABEL_HEIGHT`] tall. Cells run left to right, then top to bottom, in view (job) order.
//! A thumbnail is the view composited over [`CELL_BACKGROUND`] (where it is transparent) and
//! resized to fit its box with a Lanczos-3 filter, centred when its aspect differs.

use crate::output::raster::composite;
use crate::output::raster::{draw_label_at, fill_rect, line};
use image::{imageops::FilterType, Rgb, RgbImage, RgbaImage};

/// Border around and between cells, pixels.
pub const PADDING: u32 = 4;
/// Height of the label strip under each thumbnail: a double-size 8x8 glyph and 2 px above and
/// below it.
pub const LABEL_HEIGHT: u32 = 20;

/// The cell width from which a sheet's labels are drawn at twice the font's size (16 pixels a
/// character, 29 characters a label).
const LARGE_LABEL_CELL_WIDTH: u32 = 480;
/// Cell width when none is given, pixels: a 36-view turntable's 6x6 sheet is 1564 pixels wide.
pub const DEFAULT_CELL_WIDTH: u32 = 256;
/// Widest cell accepted: a full-size 4K render.
pub const MAX_CELL_WIDTH: u32 = 4096;
/// The sheet's colour between cells and under the labels.
pub const SHEET_BACKGROUND: [u8; 3] = [255, 255, 255];
/// What shows through a view's transparent pixels (no `--background`): a mid grey on which
/// both light and dark models stand out.
pub const CELL_BACKGROUND: [u8; 3] = [96, 96, 96];
/// Label colour.
const INK: Rgb<u8> = Rgb([20, 20, 20]);
/// Label and cross of a failed job.
const FAILED_INK: Rgb<u8> = Rgb([200, 30, 30]);

/// Where every cell of a sheet goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SheetLayout {
    /// Number of cells.
    pub count: usize,
    /// Cells per row.
    pub columns: u32,
    /// Rows of cells.
    pub rows: u32,
    /// Thumbnail box width.
    pub cell_width: u32,
    /// Thumbnail box height.
    pub thumb_height: u32,
}

impl SheetLayout {
    /// The layout of `count` cells for images of `image_size` (width, height): `columns` per row
    /// (at most `count`) or, when `None`, ⌈√count⌉ so that the grid is about square in cells;
    /// thumbnails `cell_width` wide and as tall as the image's aspect makes them (at least 1).
    /// Errors say what is wrong with the count, columns or width.
    pub fn new(
        count: usize,
        columns: Option<u32>,
        cell_width: u32,
        image_size: (u32, u32),
    ) -> Result<SheetLayout, String> {
        if count == 0 {
            return Err("no images to put on the sheet".into());
        }
        if !(1..=MAX_CELL_WIDTH).contains(&cell_width) {
            return Err(format!(
                "--sheet-cell-width {cell_width}: must be from 1 to {MAX_CELL_WIDTH} pixels"
            ));
        }
        let count_u32 = u32::try_from(count).map_err(|_| format!("{count} cells: too many"))?;
        let columns = match columns {
            Some(0) => return Err("--sheet-columns 0: must be at least 1".into()),
            Some(c) => c.min(count_u32),
            None => (count as f64).sqrt().ceil() as u32,
        };
        let rows = count_u32.div_ceil(columns);
        let (w, h) = (image_size.0.max(1), image_size.1.max(1));
        let thumb_height = ((u64::from(cell_width) * u64::from(h) + u64::from(w) / 2)
            / u64::from(w))
        .clamp(1, u64::from(MAX_CELL_WIDTH) * 4) as u32;
        let layout = SheetLayout {
            count,
            columns,
            rows,
            cell_width,
            thumb_height,
        };
        if layout.width() > u64::from(u32::MAX) || layout.height() > u64::from(u32::MAX) {
            return Err(format!(
                "{count} cells in {columns} columns make a {}x{} sheet, more than an image can hold",
                layout.width(),
                layout.height()
            ));
        }
        Ok(layout)
    }

    /// Sheet width: `columns` cells and `columns + 1` paddings.
    pub fn width(&self) -> u64 {
        u64::from(self.columns) * u64::from(self.cell_width + PADDING) + u64::from(PADDING)
    }

    /// Sheet height: `rows` cells (thumbnail and label) and `rows + 1` paddings.
    pub fn height(&self) -> u64 {
        u64::from(self.rows) * u64::from(self.thumb_height + LABEL_HEIGHT + PADDING)
            + u64::from(PADDING)
    }

    /// Pixels of the sheet.
    pub fn pixels(&self) -> u64 {
        self.width() * self.height()
    }

    /// Top-left corner of cell `index`'s thumbnail box.
    pub fn thumb_origin(&self, index: usize) -> (u32, u32) {
        let (column, row) = (index as u32 % self.columns, index as u32 / self.columns);
        (
            PADDING + column * (self.cell_width + PADDING),
            PADDING + row * (self.thumb_height + LABEL_HEIGHT + PADDING),
        )
    }

    /// Top-left corner of cell `index`'s label strip (`cell_width` x [`LABEL_HEIGHT`]), right
    /// under its thumbnail box.
    pub fn label_origin(&self, index: usize) -> (u32, u32) {
        let (x, y) = self.thumb_origin(index);
        (x, y + self.thumb_height)
    }
}

/// The size of an image of `size` scaled to fit in `frame` (both width, height) keeping its
/// aspect: as large as fits, at least 1 x 1.
pub fn fit(size: (u32, u32), frame: (u32, u32)) -> (u32, u32) {
    let (w, h) = (u64::from(size.0.max(1)), u64::from(size.1.max(1)));
    let (fw, fh) = (u64::from(frame.0), u64::from(frame.1));
    // Width-bound when w/h >= fw/fh, i.e. w*fh >= fw*h.
    let (tw, th) = if w * fh >= fw * h {
        (fw, (h * fw + w / 2) / w)
    } else {
        ((w * fh + h / 2) / h, fh)
    };
    (tw.clamp(1, fw.max(1)) as u32, th.clamp(1, fh.max(1)) as u32)
}

/// The thumbnail of a view as a cell shows it: composited over [`CELL_BACKGROUND`], resized
/// (Lanczos 3) to fit in `frame` (width, height).
pub fn thumbnail(view: &RgbaImage, frame: (u32, u32)) -> RgbImage {
    let (w, h) = fit(view.dimensions(), frame);
    let opaque = composite(view, CELL_BACKGROUND);
    if (w, h) == view.dimensions() {
        return opaque;
    }
    image::imageops::resize(&opaque, w, h, FilterType::Lanczos3)
}

/// A contact sheet being filled, cell by cell.
pub struct ContactSheet {
    layout: SheetLayout,
    image: RgbImage,
}

impl ContactSheet {
    /// An empty sheet: every cell blank until placed. The caller checks the layout's size
    /// against its pixel limit first.
    pub fn new(layout: SheetLayout) -> ContactSheet {
        let image = RgbImage::from_pixel(
            layout.width() as u32,
            layout.height() as u32,
            Rgb(SHEET_BACKGROUND),
        );
        ContactSheet { layout, image }
    }

    /// The layout.
    pub fn layout(&self) -> &SheetLayout {
        &self.layout
    }

    /// Puts `view` (straight-alpha sRGB) in cell `index`, its thumbnail centred in the box,
    /// with `label` under it.
    pub fn place(&mut self, index: usize, view: &RgbaImage, label: &str) {
        let frame = (self.layout.cell_width, self.layout.thumb_height);
        let thumb = thumbnail(view, frame);
        let (x, y) = self.layout.thumb_origin(index);
        let dx = (frame.0 - thumb.width()) / 2;
        let dy = (frame.1 - thumb.height()) / 2;
        image::imageops::replace(
            &mut self.image,
            &thumb,
            i64::from(x + dx),
            i64::from(y + dy),
        );
        self.label(index, label, INK);
    }

    /// Marks cell `index` as failed: a blank box crossed out, and `label` in red.
    pub fn place_failed(&mut self, index: usize, label: &str) {
        let (x, y) = self.layout.thumb_origin(index);
        let (w, h) = (self.layout.cell_width, self.layout.thumb_height);
        fill_rect(
            &mut self.image,
            x as i32,
            y as i32,
            w as i32,
            h as i32,
            Rgb(CELL_BACKGROUND),
        );
        let (x0, y0, x1, y1) = (x as f32, y as f32, (x + w - 1) as f32, (y + h - 1) as f32);
        let thick = (w.min(h) / 32).max(1) as i32;
        line(&mut self.image, (x0, y0), (x1, y1), thick, FAILED_INK);
        line(&mut self.image, (x0, y1), (x1, y0), thick, FAILED_INK);
        // The cross's thick ends may poke past the box: the padding stays clean.
        self.clear_padding_around(index);
        self.label(index, label, FAILED_INK);
    }

    /// Every label of a sheet at one size, set by the cell's width (a label drawn larger
    /// because it happened to be short stood out from its neighbours): double from
    /// [`LARGE_LABEL_CELL_WIDTH`] up.
    fn label(&mut self, index: usize, label: &str, color: Rgb<u8>) {
        let (x, y) = self.layout.label_origin(index);
        let width = self.layout.cell_width;
        draw_label_at(
            &mut self.image,
            (x as i32, y as i32),
            (width, LABEL_HEIGHT),
            label,
            color,
            if width >= LARGE_LABEL_CELL_WIDTH {
                2
            } else {
                1
            },
        );
    }

    fn clear_padding_around(&mut self, index: usize) {
        let (x, y) = self.layout.thumb_origin(index);
        let (w, h) = (
            self.layout.cell_width as i32,
            (self.layout.thumb_height + LABEL_HEIGHT) as i32,
        );
        let (x, y, pad) = (x as i32, y as i32, PADDING as i32);
        let bg = Rgb(SHEET_BACKGROUND);
        fill_rect(&mut self.image, x - pad, y - pad, w + 2 * pad, pad, bg);
        fill_rect(&mut self.image, x - pad, y + h, w + 2 * pad, pad, bg);
        fill_rect(&mut self.image, x - pad, y, pad, h, bg);
        fill_rect(&mut self.image, x + w, y, pad, h, bg);
        let strip = self.layout.label_origin(index);
        fill_rect(
            &mut self.image,
            strip.0 as i32,
            strip.1 as i32,
            w,
            LABEL_HEIGHT as i32,
            bg,
        );
    }

    /// The sheet as it stands.
    pub fn image(&self) -> &RgbImage {
        &self.image
    }

    /// The sheet encoded as an 8-bit RGB PNG.
    pub fn to_png(&self) -> Result<Vec<u8>, image::ImageError> {
        let mut bytes = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut bytes),
            self.image.as_raw(),
            self.image.width(),
            self.image.height(),
            image::ExtendedColorType::Rgb8,
        )?;
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_make_an_about_square_grid_unless_given() {
        for (count, columns, rows) in [
            (1, 1, 1),
            (2, 2, 1),
            (4, 2, 2),
            (5, 3, 2),
            (9, 3, 3),
            (10, 4, 3),
            (36, 6, 6),
            (37, 7, 6),
        ] {
            let l = SheetLayout::new(count, None, 100, (4, 3)).unwrap();
            assert_eq!((l.columns, l.rows), (columns, rows), "{count} cells");
            assert!(u64::from(l.columns * l.rows) >= count as u64);
            assert!(
                u64::from(l.columns * (l.rows - 1)) < count as u64,
                "no empty row"
            );
        }
        let l = SheetLayout::new(10, Some(5), 100, (4, 3)).unwrap();
        assert_eq!((l.columns, l.rows), (5, 2));
        let l = SheetLayout::new(3, Some(8), 100, (4, 3)).unwrap();
        assert_eq!((l.columns, l.rows), (3, 1), "no empty columns");
    }

    #[test]
    fn sizes_and_origins_add_up() {
        let l = SheetLayout::new(5, None, 64, (64, 48)).unwrap();
        assert_eq!(l.thumb_height, 48);
        assert_eq!(l.width(), 3 * (64 + PADDING as u64) + PADDING as u64);
        assert_eq!(
            l.height(),
            2 * (48 + LABEL_HEIGHT as u64 + PADDING as u64) + PADDING as u64
        );
        assert_eq!(l.thumb_origin(0), (PADDING, PADDING));
        assert_eq!(l.thumb_origin(2), (PADDING + 2 * (64 + PADDING), PADDING));
        assert_eq!(
            l.thumb_origin(4),
            (
                PADDING + 64 + PADDING,
                PADDING + 48 + LABEL_HEIGHT + PADDING
            )
        );
        assert_eq!(
            l.label_origin(4),
            (PADDING + 64 + PADDING, 2 * PADDING + 48 + 48 + LABEL_HEIGHT)
        );
        // The last cell ends a padding short of the sheet's edges.
        let (x, y) = l.label_origin(l.count - 1);
        assert!(u64::from(x + l.cell_width + PADDING) <= l.width());
        let (_, y_last_row) = l.label_origin(3);
        assert_eq!(u64::from(y_last_row + LABEL_HEIGHT + PADDING), l.height());
        assert_eq!(y, y_last_row);
        // Thumbnail height follows the aspect, rounded.
        assert_eq!(
            SheetLayout::new(1, None, 256, (1024, 768))
                .unwrap()
                .thumb_height,
            192
        );
        assert_eq!(
            SheetLayout::new(1, None, 100, (3, 1)).unwrap().thumb_height,
            33
        );
        assert_eq!(
            SheetLayout::new(1, None, 1, (1000, 1))
                .unwrap()
                .thumb_height,
            1
        );
    }

    #[test]
    fn bad_layouts_say_why() {
        for (count, columns, width, words) in [
            (0, None, 64, "no images"),
            (3, Some(0), 64, "--sheet-columns 0"),
            (3, None, 0, "--sheet-cell-width 0"),
            (3, None, MAX_CELL_WIDTH + 1, "--sheet-cell-width"),
            (
                2_000_000,
                Some(2_000_000),
                4096,
                "more than an image can hold",
            ),
        ] {
            let e = SheetLayout::new(count, columns, width, (4, 3)).unwrap_err();
            assert!(e.contains(words), "{e}");
        }
    }

    /// A sheet's labels are all drawn at one size, set by the cell width: a short label is
    /// not drawn larger than its neighbours.
    #[test]
    fn every_label_of_a_sheet_has_one_size() {
        // The rows of cell `index`'s label strip that hold ink.
        let inked_rows = |sheet: &ContactSheet, index: usize| {
            let (x, y) = sheet.layout().label_origin(index);
            let width = sheet.layout().cell_width;
            (y..y + LABEL_HEIGHT)
                .filter(|&row| (x..x + width).any(|col| *sheet.image().get_pixel(col, row) == INK))
                .count()
        };
        for (cell_width, font_rows) in [(256, 8), (LARGE_LABEL_CELL_WIDTH, 16)] {
            let layout = SheetLayout::new(2, None, cell_width, (4, 3)).unwrap();
            let mut sheet = ContactSheet::new(layout);
            let view = RgbaImage::from_pixel(4, 3, image::Rgba([0, 0, 0, 0]));
            sheet.place(0, &view, "Box/glTF/Box");
            sheet.place(
                1,
                &view,
                "MetalRoughSpheresNoTextures/glTF-Binary/Spheres.glb",
            );
            // Each label holds letters with ascenders and descenders ("B", "y"): the font's rows.
            for index in [0, 1] {
                let rows = inked_rows(&sheet, index);
                assert!(
                    rows > font_rows / 2 && rows <= font_rows,
                    "{cell_width}: {rows} rows"
                );
            }
            assert_eq!(inked_rows(&sheet, 0), inked_rows(&sheet, 1), "{cell_width}");
        }
    }

    #[test]
    fn fit_keeps_the_aspect() {
        assert_eq!(fit((64, 48), (32, 24)), (32, 24));
        assert_eq!(fit((100, 100), (64, 48)), (48, 48));
        assert_eq!(fit((200, 50), (64, 48)), (64, 16));
        assert_eq!(fit((10, 1000), (64, 48)), (1, 48));
        assert_eq!(fit((16, 12), (64, 48)), (64, 48), "small images grow");
    }

    /// A placed view fills its box (centred when narrower), its label is drawn in its strip,
    /// and nothing spills into the padding or the neighbouring cells.
    #[test]
    fn placed_cells_stay_in_their_boxes() {
        let l = SheetLayout::new(4, Some(2), 40, (40, 30)).unwrap();
        let mut sheet = ContactSheet::new(l);
        let red = RgbaImage::from_pixel(80, 60, image::Rgba([255, 0, 0, 255]));
        let square = RgbaImage::from_pixel(30, 30, image::Rgba([0, 0, 255, 255]));
        sheet.place(0, &red, "0");
        sheet.place(1, &square, "long label here");
        sheet.place_failed(3, "broken");
        let img = sheet.image();
        let (x, y) = l.thumb_origin(0);
        for (dx, dy) in [(0, 0), (39, 29), (20, 15)] {
            assert_eq!(
                img.get_pixel(x + dx, y + dy).0,
                [255, 0, 0],
                "cell 0 filled"
            );
        }
        // The 30x30 square is centred in the 40x30 box: 5 columns of sheet colour each side.
        let (x, y) = l.thumb_origin(1);
        assert_eq!(img.get_pixel(x + 2, y + 10).0, SHEET_BACKGROUND);
        assert_eq!(img.get_pixel(x + 5, y + 10).0, [0, 0, 255]);
        assert_eq!(img.get_pixel(x + 34, y + 10).0, [0, 0, 255]);
        assert_eq!(img.get_pixel(x + 36, y + 10).0, SHEET_BACKGROUND);
        let inked = |index: usize| {
            let (x, y) = l.label_origin(index);
            (0..l.cell_width)
                .flat_map(|dx| (0..LABEL_HEIGHT).map(move |dy| (x + dx, y + dy)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 != SHEET_BACKGROUND)
                .count()
        };
        assert!(inked(0) > 0 && inked(1) > 0 && inked(3) > 0, "labels drawn");
        assert_eq!(inked(2), 0, "an unplaced cell stays blank");
        // A failed cell is crossed: the box's corners and centre are red.
        let (x, y) = l.thumb_origin(3);
        let is_red = |p: &Rgb<u8>| p.0[0] > 150 && p.0[1] < 80;
        let red_near = |cx: u32, cy: u32| {
            (cx - 1..=cx + 1).any(|xx| (cy - 1..=cy + 1).any(|yy| is_red(img.get_pixel(xx, yy))))
        };
        assert!(is_red(img.get_pixel(x, y)), "corner");
        assert!(red_near(x + 20, y + 15), "centre");
        assert!(!is_red(img.get_pixel(x + 20, y + 2)), "between the arms");
        // Padding stays sheet-coloured everywhere.
        for yy in 0..img.height() {
            for xx in 0..PADDING {
                assert_eq!(img.get_pixel(xx, yy).0, SHEET_BACKGROUND);
                assert_eq!(img.get_pixel(img.width() - 1 - xx, yy).0, SHEET_BACKGROUND);
            }
        }
        let column_gap = PADDING + l.cell_width;
        for yy in 0..img.height() {
            for xx in column_gap..column_gap + PADDING {
                assert_eq!(img.get_pixel(xx, yy).0, SHEET_BACKGROUND, "({xx},{yy})");
            }
        }
    }

    #[test]
    fn transparent_pixels_show_the_cell_background() {
        let mut view = RgbaImage::from_pixel(2, 1, image::Rgba([0, 0, 0, 0]));
        view.put_pixel(1, 0, image::Rgba([255, 255, 255, 128]));
        let out = composite(&view, CELL_BACKGROUND);
        assert_eq!(out.get_pixel(0, 0).0, CELL_BACKGROUND);
        // 255 * 128/255 + 96 * 127/255 = 175.8
        assert_eq!(out.get_pixel(1, 0).0, [176, 176, 176]);
    }
}
