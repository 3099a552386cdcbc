// The lcm-spy image view (lcmtypes/java/vslam/spy) renders vslam.image_t
// headless: each case builds a message, paints the plugin's panel into a
// BufferedImage (also written as a PNG into the output directory, for a look)
// and checks pixels. Run by test_image_view.sh:
//   java -Djava.awt.headless=true -cp TYPES_JAR:lcm.jar ImageViewRenderTest.java OUTDIR
import java.awt.Color;
import java.awt.Graphics2D;
import java.awt.Rectangle;
import java.awt.image.BufferedImage;
import java.io.ByteArrayOutputStream;
import java.io.File;
import javax.imageio.ImageIO;
import javax.swing.Action;
import javax.swing.JDesktopPane;
import javax.swing.SwingUtilities;
import lcm.spy.ChannelData;
import vslam.image_t;
import vslam.spy.ImagePanel;
import vslam.spy.ImageViewPlugin;

public class ImageViewRenderTest {
    static File outDir;
    static int failures = 0;

    static void check(boolean ok, String what) {
        System.out.println((ok ? "ok   " : "FAIL ") + what);
        if (!ok) ++failures;
    }

    static image_t message(int width, int height, int rowStride, byte encoding, byte[] data) {
        image_t m = new image_t();
        m.utime = 1700000000250000L;
        m.seq = 42;
        m.camera = "forward";
        m.width = width;
        m.height = height;
        m.row_stride = rowStride;
        m.encoding = encoding;
        m.exposure = 1.0f;
        m.data_size = data.length;
        m.data = data;
        return m;
    }

    /** Paints panel at w x h into an image and saves it as NAME.png. */
    static BufferedImage paint(ImagePanel panel, int w, int h, String name) throws Exception {
        panel.setSize(w, h);
        BufferedImage out = new BufferedImage(w, h, BufferedImage.TYPE_INT_RGB);
        Graphics2D g = out.createGraphics();
        panel.paint(g);
        g.dispose();
        ImageIO.write(out, "png", new File(outDir, name + ".png"));
        return out;
    }

    /** The painted colour at the centre of picture pixel (x, y). */
    static Color at(ImagePanel panel, BufferedImage painted, int x, int y) {
        Rectangle r = panel.pictureArea(painted.getWidth(), painted.getHeight());
        BufferedImage picture = panel.picture();
        int px = r.x + (int) ((x + 0.5) * r.width / picture.getWidth());
        int py = r.y + (int) ((y + 0.5) * r.height / picture.getHeight());
        return new Color(painted.getRGB(px, py));
    }

    static boolean near(Color c, int r, int g, int b, int tolerance) {
        return Math.abs(c.getRed() - r) <= tolerance && Math.abs(c.getGreen() - g) <= tolerance
            && Math.abs(c.getBlue() - b) <= tolerance;
    }

    static void gray8Gradient() throws Exception {
        // 64x48, value 4*x, with 8 padding bytes per row that must not show.
        int w = 64, h = 48, stride = 72;
        byte[] data = new byte[stride * h];
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < stride; ++x) data[y * stride + x] = (byte) (x < w ? 4 * x : 255);
        }
        ImagePanel panel = new ImagePanel();
        panel.setImage(message(w, h, stride, image_t.ENCODING_GRAY8, data));
        check(panel.problem() == null, "gray8: decodes (" + panel.problem() + ")");
        BufferedImage painted = paint(panel, 3 * w, 3 * h + 40, "gray8");
        boolean gradient = true;
        for (int y : new int[] {0, h / 2, h - 1}) {
            for (int x = 0; x < w; ++x) gradient &= near(at(panel, painted, x, y), 4 * x, 4 * x, 4 * x, 0);
        }
        check(gradient, "gray8: every painted column has value 4*x, padding not shown");
        check(panel.caption().equals("forward 64x48 gray8 seq 42 t 1700000000.250000 s (3456 B)"),
              "gray8: caption '" + panel.caption() + "'");
    }

    static void bgr8Patch() throws Exception {
        // 40x30 pure blue, a 10x10 patch (B,G,R) = (30,200,90) at x 10..19, y 5..14.
        int w = 40, h = 30, stride = 3 * w;
        byte[] data = new byte[stride * h];
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                boolean patch = x >= 10 && x < 20 && y >= 5 && y < 15;
                data[y * stride + 3 * x] = (byte) (patch ? 30 : 255);
                data[y * stride + 3 * x + 1] = (byte) (patch ? 200 : 0);
                data[y * stride + 3 * x + 2] = (byte) (patch ? 90 : 0);
            }
        }
        ImagePanel panel = new ImagePanel();
        panel.setImage(message(w, h, stride, image_t.ENCODING_BGR8, data));
        check(panel.problem() == null, "bgr8: decodes (" + panel.problem() + ")");
        BufferedImage painted = paint(panel, 400, 340, "bgr8");
        boolean patch = true, background = true;
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                Color c = at(panel, painted, x, y);
                if (x >= 10 && x < 20 && y >= 5 && y < 15) patch &= near(c, 90, 200, 30, 0);
                else background &= near(c, 0, 0, 255, 0);
            }
        }
        check(patch, "bgr8: patch painted as R 90 G 200 B 30 (channel order kept)");
        check(background, "bgr8: background painted pure blue");
    }

    static void jpeg() throws Exception {
        // 64x48: left half red, right half green, through ImageIO's JPEG encoder.
        BufferedImage src = new BufferedImage(64, 48, BufferedImage.TYPE_3BYTE_BGR);
        Graphics2D g = src.createGraphics();
        g.setColor(Color.RED);
        g.fillRect(0, 0, 32, 48);
        g.setColor(Color.GREEN);
        g.fillRect(32, 0, 32, 48);
        g.dispose();
        ByteArrayOutputStream bytes = new ByteArrayOutputStream();
        ImageIO.write(src, "jpeg", bytes);
        ImagePanel panel = new ImagePanel();
        panel.setImage(message(64, 48, 0, image_t.ENCODING_JPEG, bytes.toByteArray()));
        check(panel.problem() == null, "jpeg: decodes (" + panel.problem() + ")");
        BufferedImage painted = paint(panel, 256, 232, "jpeg");
        check(near(at(panel, painted, 8, 24), 255, 0, 0, 40), "jpeg: left half red");
        check(near(at(panel, painted, 56, 24), 0, 255, 0, 40), "jpeg: right half green");

        // The same bytes in a message claiming another size: refused before decoding.
        panel.setImage(message(32, 24, 0, image_t.ENCODING_JPEG, bytes.toByteArray()));
        check(panel.picture() == null && "JPEG data is 64x48 but the message says 32x24".equals(panel.problem()),
              "jpeg: size mismatch named (" + panel.problem() + ")");
    }

    /** A message that is no picture shows text naming the problem, and paints. */
    static void malformed(String name, image_t m, String expected) throws Exception {
        ImagePanel panel = new ImagePanel();
        panel.setImage(m);
        String problem = panel.problem();
        check(panel.picture() == null && problem != null && problem.contains(expected),
              "malformed " + name + ": '" + problem + "' names '" + expected + "'");
        BufferedImage painted = paint(panel, 320, 120, "malformed_" + name);
        boolean redText = false;  // the message is drawn in light red
        for (int y = 0; y < 40 && !redText; ++y) {
            for (int x = 0; x < 320 && !redText; ++x) redText = near(new Color(painted.getRGB(x, y)), 255, 110, 110, 60);
        }
        check(redText, "malformed " + name + ": message painted");
    }

    static void malformedCases() throws Exception {
        malformed("short", message(64, 48, 64, image_t.ENCODING_GRAY8, new byte[64 * 47]),
                  "3008 data bytes, but height 48 x row_stride 64 needs 3072 (gray8)");
        malformed("stride", message(40, 30, 100, image_t.ENCODING_BGR8, new byte[100 * 30]),
                  "row_stride 100 is less than width 40 x 3 bytes per pixel (bgr8)");
        malformed("encoding", message(4, 4, 4, (byte) 7, new byte[16]),
                  "unknown encoding 7 (known: 0 gray8, 1 bgr8, 2 jpeg)");
        malformed("jpeg_garbage", message(64, 48, 0, image_t.ENCODING_JPEG, new byte[] {1, 2, 3, 4, 5}),
                  "JPEG data (5 bytes) does not decode");
        malformed("size", message(0, 48, 0, image_t.ENCODING_GRAY8, new byte[0]),
                  "size 0x48 is not a picture");
        malformed("huge", message(100000, 100000, 100000, image_t.ENCODING_GRAY8, new byte[16]),
                  "size 100000x100000 is more than");
        image_t lying = message(4, 4, 4, image_t.ENCODING_GRAY8, new byte[16]);
        lying.data_size = 17;
        malformed("data_size", lying, "data_size 17 but 16 data bytes");
    }

    /** The plugin as lcm-spy drives it: name, fingerprint, a view that follows the channel. */
    static void plugin() throws Exception {
        ImageViewPlugin plugin = new ImageViewPlugin();
        check(plugin.canHandle(image_t.LCM_FINGERPRINT), "plugin: handles vslam.image_t");
        check(!plugin.canHandle(vslam.odometry_t.LCM_FINGERPRINT), "plugin: not vslam.odometry_t");
        Action named = plugin.getAction(null, null);  // what lcm-spy does to build its menu
        check("Image view".equals(named.getValue(Action.NAME)), "plugin: menu entry 'Image view'");
        named.actionPerformed(null);  // with no desktop: nothing, no exception

        ChannelData channel = new ChannelData();
        channel.name = "CAM_FORWARD_IMAGE";
        channel.fingerprint = image_t.LCM_FINGERPRINT;
        JDesktopPane desktop = new JDesktopPane();
        desktop.setSize(500, 400);
        ImageViewPlugin.View[] view = new ImageViewPlugin.View[1];
        SwingUtilities.invokeAndWait(() -> plugin.getAction(desktop, channel).actionPerformed(null));
        check(desktop.getAllFrames().length == 1 && desktop.getAllFrames()[0] instanceof ImageViewPlugin.View,
              "plugin: opens one view in lcm-spy's desktop");
        view[0] = (ImageViewPlugin.View) desktop.getAllFrames()[0];
        check("no image yet".equals(view[0].panel().caption()), "plugin: view waits for a first frame");

        byte[] gray = new byte[16];
        image_t first = message(4, 4, 4, image_t.ENCODING_GRAY8, gray);
        image_t second = message(4, 4, 4, image_t.ENCODING_GRAY8, gray);
        second.seq = 43;
        boolean[] changed = new boolean[3];
        channel.last = first;  // as lcm-spy's receive thread does per message
        SwingUtilities.invokeAndWait(() -> changed[0] = view[0].refresh());
        SwingUtilities.invokeAndWait(() -> changed[1] = view[0].refresh());
        check(changed[0] && !changed[1] && view[0].panel().caption().contains("seq 42"),
              "plugin: shows the channel's frame once");
        channel.last = second;
        SwingUtilities.invokeAndWait(() -> changed[2] = view[0].refresh());
        check(changed[2] && view[0].panel().caption().contains("seq 43"), "plugin: follows the next frame");
        SwingUtilities.invokeAndWait(() -> view[0].dispose());
    }

    public static void main(String[] args) throws Exception {
        outDir = new File(args.length > 0 ? args[0] : ".");
        outDir.mkdirs();
        gray8Gradient();
        bgr8Patch();
        jpeg();
        malformedCases();
        plugin();
        if (failures > 0) {
            System.out.println("FAIL: " + failures + " check(s) failed; pictures in " + outDir);
            System.exit(1);
        }
        System.out.println("PASS: image view draws gray8, bgr8 and jpeg and names malformed images; pictures in " + outDir);
        System.exit(0);
    }
}
