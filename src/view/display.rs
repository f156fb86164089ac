//! The live view's display: an OS window (winit; "window" alone, in this
//! file, means that OS window), drawn with the tracker's own wgpu device.
//!
//! The tracker runs on the calling thread and the window lives there too:
//! instead of handing the thread to winit's event loop, [`DisplaySink`]
//! pumps the window's pending events (without waiting) each time a frame
//! is finished, then draws that frame. So tracking never waits for the
//! window: the view shows the newest frame the moment it is tracked, the
//! surface presents in mailbox or immediate mode where the driver offers
//! one (FIFO, which waits for vertical sync, only where nothing else is
//! offered), and a frame whose surface image is not ready (window hidden,
//! resized) is skipped rather than waited for. Closing the window, `Esc`
//! or `q` answer [`Flow::Stop`]: the run ends there as at the end of the
//! sequence.

use super::clicks::{ClickKey, RawEvent};
use super::picture::compose;
use super::present::Presenter;
use super::sink::{Flow, FrameSink, ViewError, ViewFrame};
use crate::gpu::GpuContext;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::platform::pump_events::EventLoopExtPumpEvents;
use winit::window::{Window as OsWindow, WindowAttributes, WindowId};

/// How long [`DisplaySink::open`] waits for the window system to create the
/// window.
const OPEN_TIMEOUT: Duration = Duration::from_secs(10);

/// The window's events, as far as the view cares.
struct Handler {
    attributes: Option<WindowAttributes>,
    os_window: Option<Arc<OsWindow>>,
    error: Option<String>,
    close: bool,
    resized: bool,
    /// The pointer's last position, window pixels.
    cursor: (f64, f64),
    /// Clicks and keys since they were last taken ([`DisplaySink::show`]).
    events: Vec<RawEvent>,
}

impl ApplicationHandler for Handler {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(attributes) = self.attributes.take() {
            match event_loop.create_window(attributes) {
                Ok(w) => self.os_window = Some(Arc::new(w)),
                Err(e) => self.error = Some(e.to_string()),
            }
        }
    }

    fn window_event(&mut self, _: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => {
                self.close = true;
                self.events.push(RawEvent::Close);
            }
            WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        logical_key,
                        state: ElementState::Pressed,
                        ..
                    },
                ..
            } => match logical_key.as_ref() {
                Key::Named(NamedKey::Escape) => {
                    self.close = true;
                    self.events.push(RawEvent::Key(ClickKey::Escape));
                }
                Key::Character(c) if c.eq_ignore_ascii_case("q") => {
                    self.close = true;
                    self.events.push(RawEvent::Key(ClickKey::Q));
                }
                Key::Named(NamedKey::Enter) => self.events.push(RawEvent::Key(ClickKey::Enter)),
                Key::Named(NamedKey::Backspace) => {
                    self.events.push(RawEvent::Key(ClickKey::Backspace))
                }
                _ => {}
            },
            WindowEvent::CursorMoved { position, .. } => self.cursor = (position.x, position.y),
            WindowEvent::MouseInput {
                state: ElementState::Pressed,
                button,
                ..
            } => match button {
                MouseButton::Left => self
                    .events
                    .push(RawEvent::LeftClick(self.cursor.0, self.cursor.1)),
                MouseButton::Right => self.events.push(RawEvent::RightClick),
                _ => {}
            },
            WindowEvent::Resized(_) | WindowEvent::ScaleFactorChanged { .. } => self.resized = true,
            _ => {}
        }
    }
}

/// What a [`DisplaySink`] did.
#[derive(Debug, Clone, Copy, Default)]
pub struct DisplayStats {
    /// Frames drawn into the window.
    pub shown: usize,
    /// Frames skipped because the window's surface was not ready.
    pub skipped: usize,
    /// Time spent composing, drawing and presenting, in all.
    pub busy: Duration,
}

/// The live view: an OS window showing each finished frame ([`compose`])
/// as it is tracked.
pub struct DisplaySink {
    ctx: GpuContext,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    view_format: wgpu::TextureFormat,
    presenter: Presenter,
    os_window: Arc<OsWindow>,
    handler: Handler,
    event_loop: EventLoop<()>,
    sized: bool,
    stats: DisplayStats,
}

impl DisplaySink {
    /// Opens an OS window titled `title` on the display, drawn by `ctx`'s
    /// device. Fails with [`ViewError::NoDisplay`] where there is no
    /// display (no `DISPLAY` nor `WAYLAND_DISPLAY`, or the connection
    /// fails), before anything else happens.
    pub fn open(ctx: &GpuContext, title: &str) -> Result<Self, ViewError> {
        let mut event_loop = build_event_loop()?;
        let mut handler = Handler {
            attributes: Some(
                OsWindow::default_attributes()
                    .with_title(title)
                    .with_inner_size(PhysicalSize::new(640, 480)),
            ),
            os_window: None,
            error: None,
            close: false,
            resized: false,
            cursor: (0.0, 0.0),
            events: Vec::new(),
        };
        let start = Instant::now();
        let os_window = loop {
            event_loop.pump_app_events(Some(Duration::from_millis(10)), &mut handler);
            if let Some(e) = handler.error.take() {
                return Err(ViewError::Open(e));
            }
            if let Some(w) = &handler.os_window {
                break w.clone();
            }
            if start.elapsed() > OPEN_TIMEOUT {
                return Err(ViewError::Open(format!(
                    "the window system did not create the window within {} s",
                    OPEN_TIMEOUT.as_secs()
                )));
            }
        };
        let surface_error = |reason: String| ViewError::Surface {
            adapter: ctx.describe(),
            reason,
        };
        let surface = ctx
            .instance
            .create_surface(os_window.clone())
            .map_err(|e| surface_error(e.to_string()))?;
        if !ctx.adapter.is_surface_supported(&surface) {
            return Err(surface_error(
                "the adapter cannot present to this window (try another --adapter)".into(),
            ));
        }
        let caps = surface.get_capabilities(&ctx.adapter);
        let format = choose_format(&caps.formats)
            .ok_or_else(|| surface_error("the surface offers no 8-bit RGBA format".into()))?;
        let view_format = format.remove_srgb_suffix();
        let present_mode = [
            wgpu::PresentMode::Mailbox,
            wgpu::PresentMode::Immediate,
            wgpu::PresentMode::Fifo,
        ]
        .into_iter()
        .find(|m| caps.present_modes.contains(m))
        .unwrap_or(wgpu::PresentMode::Fifo);
        let size = os_window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode,
            desired_maximum_frame_latency: 1,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: if view_format == format {
                vec![]
            } else {
                vec![view_format]
            },
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        ctx.catch("configuring the window's surface", || {
            surface.configure(&ctx.device, &config)
        })?;
        log::info!(
            "live view: {format:?} surface, {present_mode:?} presentation, on {}",
            ctx.describe()
        );
        let presenter = Presenter::new(ctx, view_format)?;
        Ok(Self {
            ctx: ctx.clone(),
            surface,
            config,
            view_format,
            presenter,
            os_window,
            handler,
            event_loop,
            sized: false,
            stats: DisplayStats::default(),
        })
    }

    /// What the window did so far.
    pub fn stats(&self) -> DisplayStats {
        self.stats
    }

    /// Shows `picture` (the window takes its size the first time), waits up
    /// to `wait` for the window's events and returns the clicks and keys
    /// since the last call (`splattrack init --click`). A picture the
    /// surface had no image for is skipped; the next call draws again.
    pub fn show(
        &mut self,
        picture: &image::RgbaImage,
        wait: Duration,
    ) -> Result<Vec<RawEvent>, ViewError> {
        self.size_to(picture);
        if self.draw(picture)? {
            self.stats.shown += 1;
        } else {
            self.stats.skipped += 1;
        }
        self.event_loop
            .pump_app_events(Some(wait), &mut self.handler);
        Ok(std::mem::take(&mut self.handler.events))
    }

    /// The window's inner size, pixels.
    pub fn inner_size(&self) -> (u32, u32) {
        let s = self.os_window.inner_size();
        (s.width, s.height)
    }

    /// The window takes the first picture's size; after that the user's
    /// size holds and pictures are scaled to fit.
    fn size_to(&mut self, picture: &image::RgbaImage) {
        if !self.sized {
            self.sized = true;
            let _ = self
                .os_window
                .request_inner_size(PhysicalSize::new(picture.width(), picture.height()));
            self.pump();
        }
    }

    /// Handles the window's pending events without waiting; true when the
    /// user asked to stop (window closed, `Esc`, `q`).
    fn pump(&mut self) -> bool {
        self.event_loop
            .pump_app_events(Some(Duration::ZERO), &mut self.handler);
        self.handler.close
    }

    fn reconfigure(&mut self) -> Result<(), ViewError> {
        let size = self.os_window.inner_size();
        self.config.width = size.width.max(1);
        self.config.height = size.height.max(1);
        self.ctx.catch("configuring the window's surface", || {
            self.surface.configure(&self.ctx.device, &self.config)
        })?;
        Ok(())
    }

    /// Draws `picture` into the window; false when the surface had no
    /// image ready (the frame is skipped, never waited for).
    fn draw(&mut self, picture: &image::RgbaImage) -> Result<bool, ViewError> {
        if std::mem::take(&mut self.handler.resized) {
            self.reconfigure()?;
        }
        let texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => t,
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
                self.handler.resized = true;
                t
            }
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.reconfigure()?;
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                self.ctx.check()?;
                return Err(ViewError::Surface {
                    adapter: self.ctx.describe(),
                    reason: "validation error acquiring the window's image".into(),
                });
            }
        };
        let view = texture.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(self.view_format),
            ..Default::default()
        });
        let dst = (texture.texture.width(), texture.texture.height());
        let mut enc = self.ctx.encoder();
        self.presenter
            .draw(&self.ctx, &mut enc, picture, &view, dst)?;
        self.ctx.submit(enc);
        self.os_window.pre_present_notify();
        self.ctx.queue.present(texture);
        self.ctx.check()?;
        Ok(true)
    }
}

impl FrameSink for DisplaySink {
    fn frame(&mut self, frame: &ViewFrame<'_>) -> Result<Flow, ViewError> {
        let t0 = Instant::now();
        if self.pump() {
            return Ok(Flow::Stop);
        }
        let picture = compose(frame);
        self.size_to(&picture);
        if self.draw(&picture)? {
            self.stats.shown += 1;
        } else {
            self.stats.skipped += 1;
        }
        let stop = self.pump();
        // Clicks mean nothing while tracking.
        self.handler.events.clear();
        self.stats.busy += t0.elapsed();
        Ok(if stop { Flow::Stop } else { Flow::Continue })
    }
}

/// The event loop, or why there is no display. On Linux and the BSDs it
/// may be created off the main thread (tests, embedding programs).
fn build_event_loop() -> Result<EventLoop<()>, ViewError> {
    #[allow(unused_mut)] // mutated on Linux and the BSDs only
    let mut builder = EventLoop::builder();
    #[cfg(all(unix, not(target_vendor = "apple"), not(target_os = "android")))]
    {
        use winit::platform::x11::EventLoopBuilderExtX11;
        builder.with_any_thread(true);
    }
    builder.build().map_err(|e| match e {
        winit::error::EventLoopError::Os(_) | winit::error::EventLoopError::NotSupported(_) => {
            ViewError::NoDisplay(no_display_reason(&e.to_string()))
        }
        other => ViewError::Open(other.to_string()),
    })
}

/// winit's reason, without its source location, with what to do.
fn no_display_reason(winit: &str) -> String {
    let reason = winit
        .strip_prefix("os error at ")
        .and_then(|r| r.split_once(": "))
        .map_or(winit, |(_, r)| r)
        .trim_end_matches('.');
    format!("{reason} (run it in a desktop session, or without --view)")
}

/// An 8-bit RGBA or BGRA format of the surface, non-sRGB first (the
/// picture's bytes are sRGB already; an sRGB surface is drawn through its
/// non-sRGB view).
fn choose_format(formats: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
    use wgpu::TextureFormat as F;
    [
        F::Bgra8Unorm,
        F::Rgba8Unorm,
        F::Bgra8UnormSrgb,
        F::Rgba8UnormSrgb,
    ]
    .into_iter()
    .find(|f| formats.contains(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_prefer_plain_8_bit() {
        use wgpu::TextureFormat as F;
        assert_eq!(
            choose_format(&[F::Bgra8UnormSrgb, F::Bgra8Unorm]),
            Some(F::Bgra8Unorm)
        );
        assert_eq!(
            choose_format(&[F::Rgba16Float, F::Rgba8UnormSrgb]),
            Some(F::Rgba8UnormSrgb)
        );
        assert_eq!(choose_format(&[F::Rgba16Float]), None);
    }

    #[test]
    fn the_no_display_reason_drops_the_source_location() {
        let r = no_display_reason(
            "os error at src/platform_impl/linux/mod.rs:764: neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set.",
        );
        assert_eq!(
            r,
            "neither WAYLAND_DISPLAY nor WAYLAND_SOCKET nor DISPLAY is set (run it in a desktop session, or without --view)"
        );
    }
}
