//! An undo/redo history of editor states, for apps that edit meshes, poses or clips. Pure
//! data; no Bevy. The sandbox and character examples keep their undoable state in one.

/// Undo and redo stacks of states `T` (snapshots of what an edit changes).
///
/// Record the state *before* each edit with [`UndoStack::checkpoint`]; [`UndoStack::undo`]
/// and [`UndoStack::redo`] take the state shown now and give the one to show instead.
///
/// ```
/// use bevy_wii_deform::history::UndoStack;
/// let mut history = UndoStack::new(100);
/// let mut text = String::from("a");
/// history.checkpoint(text.clone());
/// text.push('b');
/// text = history.undo(text).unwrap();
/// assert_eq!(text, "a");
/// text = history.redo(text).unwrap();
/// assert_eq!(text, "ab");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct UndoStack<T> {
    undo: Vec<T>,
    redo: Vec<T>,
    limit: usize,
}

impl<T> Default for UndoStack<T> {
    fn default() -> Self {
        Self::new(256)
    }
}

impl<T> UndoStack<T> {
    /// An empty history keeping at most `limit` undo steps (the oldest are dropped).
    pub fn new(limit: usize) -> Self {
        Self {
            undo: Vec::new(),
            redo: Vec::new(),
            limit: limit.max(1),
        }
    }

    /// Records the state before an edit; a new edit drops what could be redone.
    pub fn checkpoint(&mut self, before: T) {
        if self.undo.len() == self.limit {
            self.undo.remove(0);
        }
        self.undo.push(before);
        self.redo.clear();
    }

    /// The state to go back to, given the state `now` (kept for redo); `None` (and `now`
    /// dropped) when there is nothing to undo.
    pub fn undo(&mut self, now: T) -> Option<T> {
        let before = self.undo.pop()?;
        self.redo.push(now);
        Some(before)
    }

    /// The state undone last, given the state `now` (kept for undo); `None` when there is
    /// nothing to redo.
    pub fn redo(&mut self, now: T) -> Option<T> {
        let after = self.redo.pop()?;
        self.undo.push(now);
        Some(after)
    }

    /// There is something to undo.
    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    /// There is something to redo.
    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Forgets everything (e.g. a new model was loaded).
    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undo_and_redo_walk_the_states_and_a_new_edit_drops_redo() {
        let mut h = UndoStack::new(2);
        assert_eq!(h.undo(0), None);
        h.checkpoint(1);
        h.checkpoint(2);
        h.checkpoint(3); // 1 falls off (limit 2)
        assert_eq!(h.undo(4), Some(3));
        assert_eq!(h.undo(3), Some(2));
        assert_eq!(h.undo(2), None);
        assert_eq!(h.redo(2), Some(3));
        assert!(h.can_redo());
        h.checkpoint(3);
        assert!(!h.can_redo());
        assert_eq!(h.redo(9), None);
    }
}
