//! The window system's event loop: window events routed to the panel and the viewer.

use super::headless::Headless;
use super::input::zoom;
use super::state::ViewState;
use super::viewer::Viewer;
use dispmap::context::ContextOptions;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseScrollDelta, WindowEvent};
use winit::event_loop::ActiveEventLoop;
use winit::window::WindowId;

pub(super) struct App {
    pub(super) options: ContextOptions,
    pub(super) state: ViewState,
    pub(super) headless: Option<Headless>,
    pub(super) viewer: Option<Viewer>,
    pub(super) error: Option<anyhow::Error>,
    /// The scripted frames all ran.
    pub(super) done: bool,
    /// Draw the panel (not `--no-ui`).
    pub(super) ui: bool,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.viewer.is_some() {
            return;
        }
        match Viewer::new(
            event_loop,
            &self.options,
            &self.state,
            self.headless.is_some(),
            self.ui,
        ) {
            Ok(v) => self.viewer = Some(v),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(viewer) = self.viewer.as_mut() else {
            return;
        };
        // The panel sees input first; what it uses does not move the camera.
        let mut to_panel = false;
        if self.headless.is_none()
            && let Some(gui) = viewer.gui.as_mut()
        {
            let consumed = gui.on_event(&viewer.window, &event);
            to_panel = match &event {
                WindowEvent::KeyboardInput { .. } => gui.wants_keyboard(),
                WindowEvent::MouseInput {
                    state: ElementState::Released,
                    ..
                } => false,
                WindowEvent::CursorMoved { .. } => false,
                _ => consumed || gui.wants_pointer(),
            };
        }
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::RedrawRequested => {
                match viewer.frame(&mut self.state, self.headless.as_mut()) {
                    Ok(Flow::Continue) => Ok(()),
                    Ok(Flow::Done) => {
                        self.done = true;
                        event_loop.exit();
                        Ok(())
                    }
                    Err(e) => Err(e),
                }
            }
            WindowEvent::ModifiersChanged(m) => {
                viewer.modifiers = m.state();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } if self.headless.is_none() && !to_panel => {
                match viewer.key(&mut self.state, &event) {
                    Ok(true) => {
                        event_loop.exit();
                        Ok(())
                    }
                    Ok(false) => Ok(()),
                    Err(e) => Err(e),
                }
            }
            WindowEvent::MouseInput { state, button, .. }
                if self.headless.is_none() && !to_panel =>
            {
                viewer.mouse_button(button, state == ElementState::Pressed);
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } if self.headless.is_none() => {
                viewer.cursor(&mut self.state, [position.x as f32, position.y as f32]);
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } if self.headless.is_none() && !to_panel => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                zoom(&mut self.state.settings.scene, lines);
                Ok(())
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(v) = &self.viewer {
            v.window.request_redraw();
        }
    }
}

pub(super) enum Flow {
    Continue,
    Done,
}
