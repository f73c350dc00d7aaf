//! (module under construction on its branch)
