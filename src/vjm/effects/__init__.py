"""The effect library: physical effects a stiffness model may leave out, their model edits and predictions."""
