"""What the dove is asked to do: path control, path shapes, judged flight tasks and the
interactive viewer."""
