//! The OpenGL-style matrix stack.

use glam::Mat4;

use crate::CoreError;

/// Deepest stack allowed (OpenGL guarantees 32 for the modelview stack).
pub const MATRIX_STACK_LIMIT: usize = 64;

/// A stack of matrices whose top is the current transform.
#[derive(Clone, Debug, PartialEq)]
pub struct MatrixStack {
    stack: Vec<Mat4>,
}

impl Default for MatrixStack {
    fn default() -> Self {
        Self {
            stack: vec![Mat4::IDENTITY],
        }
    }
}

impl MatrixStack {
    /// The current matrix.
    #[must_use]
    pub fn top(&self) -> Mat4 {
        *self.stack.last().expect("the stack always holds one matrix")
    }

    pub(crate) fn top_mut(&mut self) -> &mut Mat4 {
        self.stack.last_mut().expect("the stack always holds one matrix")
    }

    /// Depth (1 when nothing is pushed).
    #[must_use]
    pub fn depth(&self) -> usize {
        self.stack.len()
    }

    pub(crate) fn push(&mut self) -> Result<(), CoreError> {
        if self.stack.len() >= MATRIX_STACK_LIMIT {
            return Err(CoreError::StackOverflow {
                limit: MATRIX_STACK_LIMIT,
            });
        }
        self.stack.push(self.top());
        Ok(())
    }

    pub(crate) fn pop(&mut self) -> Result<(), CoreError> {
        if self.stack.len() <= 1 {
            return Err(CoreError::StackUnderflow);
        }
        self.stack.pop();
        Ok(())
    }
}
