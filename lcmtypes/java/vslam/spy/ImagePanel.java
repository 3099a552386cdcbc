package vslam.spy;

import java.awt.Color;
import java.awt.Dimension;
import java.awt.Font;
import java.awt.FontMetrics;
import java.awt.Graphics;
import java.awt.Graphics2D;
import java.awt.Rectangle;
import java.awt.RenderingHints;
import java.awt.image.BufferedImage;
import java.awt.image.DataBufferByte;
import java.io.ByteArrayInputStream;
import java.io.IOException;
import java.util.Iterator;
import javax.imageio.ImageIO;
import javax.imageio.ImageReader;
import javax.imageio.stream.ImageInputStream;
import javax.swing.JPanel;
import vslam.image_t;

/**
 * Draws one vslam.image_t: the picture scaled to fit (aspect kept, nearest
 * neighbour so single pixels stay visible) above a one-line caption with the
 * camera, size, encoding, seq and time. A message that does not describe a
 * picture is shown as text saying what is wrong; nothing here throws on bad
 * input, since lcm-spy shows whatever arrives on the bus.
 */
public class ImagePanel extends JPanel {
    private static final long serialVersionUID = 1L;

    /** Larger images are refused before decoding (a JPEG header can claim anything). */
    static final long MAX_PIXELS = 16L * 1024 * 1024;

    private BufferedImage picture;  // null while there is nothing to draw
    private String caption = "no image yet";
    private String problem;  // why the last message shows no picture, or null

    public ImagePanel() {
        setBackground(Color.DARK_GRAY);
        setPreferredSize(new Dimension(640, 480 + captionHeight()));
    }

    /** Shows msg (null: nothing received yet). */
    public void setImage(image_t msg) {
        if (msg == null) {
            picture = null;
            caption = "no image yet";
            problem = null;
        } else {
            caption = caption(msg);
            try {
                picture = decode(msg);
                problem = null;
            } catch (IllegalArgumentException e) {
                picture = null;
                problem = e.getMessage();
            }
        }
        repaint();
    }

    public BufferedImage picture() {
        return picture;
    }

    public String caption() {
        return caption;
    }

    /** Why the shown message has no picture, or null when it has one. */
    public String problem() {
        return problem;
    }

    /** Where paint puts the picture in a panel of the given size. */
    public Rectangle pictureArea(int panelWidth, int panelHeight) {
        if (picture == null) return new Rectangle();
        int areaHeight = Math.max(1, panelHeight - captionHeight());
        double scale = Math.min((double) panelWidth / picture.getWidth(),
                                (double) areaHeight / picture.getHeight());
        int w = Math.max(1, (int) Math.round(picture.getWidth() * scale));
        int h = Math.max(1, (int) Math.round(picture.getHeight() * scale));
        return new Rectangle((panelWidth - w) / 2, (areaHeight - h) / 2, w, h);
    }

    @Override
    protected void paintComponent(Graphics g) {
        super.paintComponent(g);
        Graphics2D g2 = (Graphics2D) g;
        int w = getWidth();
        int h = getHeight();
        g2.setFont(captionFont());
        FontMetrics fm = g2.getFontMetrics();
        if (picture != null) {
            Rectangle r = pictureArea(w, h);
            g2.setRenderingHint(RenderingHints.KEY_INTERPOLATION,
                                RenderingHints.VALUE_INTERPOLATION_NEAREST_NEIGHBOR);
            g2.drawImage(picture, r.x, r.y, r.width, r.height, null);
        } else if (problem != null) {
            g2.setColor(new Color(255, 110, 110));
            drawWrapped(g2, "Cannot draw this image: " + problem, 8, fm.getAscent() + 8, w - 16);
        }
        g2.setRenderingHint(RenderingHints.KEY_TEXT_ANTIALIASING,
                            RenderingHints.VALUE_TEXT_ANTIALIAS_ON);
        g2.setColor(Color.BLACK);
        g2.fillRect(0, h - captionHeight(), w, captionHeight());
        g2.setColor(Color.WHITE);
        g2.drawString(caption, 6, h - captionHeight() + 4 + fm.getAscent());
    }

    private static Font captionFont() {
        return new Font(Font.MONOSPACED, Font.PLAIN, 12);
    }

    private int captionHeight() {
        return getFontMetrics(captionFont()).getHeight() + 8;
    }

    private static void drawWrapped(Graphics2D g, String text, int x, int y, int width) {
        FontMetrics fm = g.getFontMetrics();
        StringBuilder line = new StringBuilder();
        for (String word : text.split(" ")) {
            if (line.length() > 0 && fm.stringWidth(line + " " + word) > width) {
                g.drawString(line.toString(), x, y);
                y += fm.getHeight();
                line.setLength(0);
            }
            if (line.length() > 0) line.append(' ');
            line.append(word);
        }
        g.drawString(line.toString(), x, y);
    }

    static String encodingName(byte encoding) {
        switch (encoding) {
            case image_t.ENCODING_GRAY8: return "gray8";
            case image_t.ENCODING_BGR8: return "bgr8";
            case image_t.ENCODING_JPEG: return "jpeg";
            default: return "encoding " + encoding;
        }
    }

    /** "forward 640x480 bgr8 seq 12 t 1700000000.250000 s (921600 B)". */
    public static String caption(image_t msg) {
        long seconds = Math.floorDiv(msg.utime, 1000000L);
        long micros = Math.floorMod(msg.utime, 1000000L);
        return String.format("%s %dx%d %s seq %d t %d.%06d s (%d B)",
                             msg.camera == null ? "?" : msg.camera, msg.width, msg.height,
                             encodingName(msg.encoding), msg.seq, seconds, micros,
                             msg.data == null ? 0 : msg.data.length);
    }

    /**
     * The picture msg describes. Throws IllegalArgumentException naming what
     * is wrong: a size that is not positive or too large, a data_size that
     * differs from the data, raw data shorter than height x row_stride, a row
     * stride too small for the width, JPEG bytes that do not decode or decode
     * to another size, an unknown encoding.
     */
    public static BufferedImage decode(image_t msg) {
        if (msg.data == null || msg.data_size != msg.data.length) {
            throw new IllegalArgumentException(String.format(
                "data_size %d but %d data bytes", msg.data_size,
                msg.data == null ? 0 : msg.data.length));
        }
        if (msg.width <= 0 || msg.height <= 0) {
            throw new IllegalArgumentException(
                String.format("size %dx%d is not a picture", msg.width, msg.height));
        }
        if ((long) msg.width * msg.height > MAX_PIXELS) {
            throw new IllegalArgumentException(String.format(
                "size %dx%d is more than %d pixels", msg.width, msg.height, MAX_PIXELS));
        }
        switch (msg.encoding) {
            case image_t.ENCODING_GRAY8:
                return raw(msg, 1, BufferedImage.TYPE_BYTE_GRAY);
            case image_t.ENCODING_BGR8:
                // TYPE_3BYTE_BGR stores each pixel as B, G, R: the message's order.
                return raw(msg, 3, BufferedImage.TYPE_3BYTE_BGR);
            case image_t.ENCODING_JPEG:
                return jpeg(msg);
            default:
                throw new IllegalArgumentException(String.format(
                    "unknown encoding %d (known: %d gray8, %d bgr8, %d jpeg)", msg.encoding,
                    image_t.ENCODING_GRAY8, image_t.ENCODING_BGR8, image_t.ENCODING_JPEG));
        }
    }

    private static BufferedImage raw(image_t msg, int channels, int type) {
        int rowBytes = msg.width * channels;  // cannot overflow: width * height <= MAX_PIXELS
        if (msg.row_stride < rowBytes) {
            throw new IllegalArgumentException(String.format(
                "row_stride %d is less than width %d x %d bytes per pixel (%s)", msg.row_stride,
                msg.width, channels, encodingName(msg.encoding)));
        }
        long needed = (long) msg.row_stride * msg.height;
        if (msg.data.length < needed) {
            throw new IllegalArgumentException(String.format(
                "%d data bytes, but height %d x row_stride %d needs %d (%s)", msg.data.length,
                msg.height, msg.row_stride, needed, encodingName(msg.encoding)));
        }
        BufferedImage image = new BufferedImage(msg.width, msg.height, type);
        byte[] pixels = ((DataBufferByte) image.getRaster().getDataBuffer()).getData();
        for (int row = 0; row < msg.height; ++row) {
            System.arraycopy(msg.data, row * msg.row_stride, pixels, row * rowBytes, rowBytes);
        }
        return image;
    }

    private static BufferedImage jpeg(image_t msg) {
        Iterator<ImageReader> readers = ImageIO.getImageReadersByFormatName("jpeg");
        if (!readers.hasNext()) throw new IllegalArgumentException("this Java has no JPEG decoder");
        ImageReader reader = readers.next();
        String mismatch = null;
        BufferedImage image = null;
        try (ImageInputStream in =
                 ImageIO.createImageInputStream(new ByteArrayInputStream(msg.data))) {
            reader.setInput(in, true, true);
            // Compare the header's size first: a hostile JPEG would otherwise
            // make the decoder allocate whatever size it claims.
            int w = reader.getWidth(0);
            int h = reader.getHeight(0);
            if (w != msg.width || h != msg.height) {
                mismatch = String.format("JPEG data is %dx%d but the message says %dx%d", w, h,
                                         msg.width, msg.height);
            } else {
                image = reader.read(0);
            }
        } catch (IOException | RuntimeException e) {
            throw new IllegalArgumentException(
                "JPEG data (" + msg.data.length + " bytes) does not decode: " + e.getMessage());
        } finally {
            reader.dispose();
        }
        if (mismatch != null) throw new IllegalArgumentException(mismatch);
        return image;
    }
}
