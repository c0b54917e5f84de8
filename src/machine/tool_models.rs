//! The error model per tool: the volumetric error at the tip depends on the
//! tool's length (every angular error acts on it as a lever), so a program
//! that changes tools is evaluated with one model per length.
//!
//! [`ToolModels`] holds the base model and a copy for each other length seen;
//! [`ToolModels::prepare`] adds lengths (sequential), [`ToolModels::get`] reads
//! them (shared, for parallel solves). Tool 0, the default tool, is the base
//! model's own tool (the machine file's `[tool]`).
use super::ErrorModel;
use crate::gcode::ToolInUse;

/// The error model per tool length: the base model and a copy for each other length seen.
#[derive(Debug)]
pub struct ToolModels<'m> {
    base: &'m ErrorModel,
    /// Other tool lengths (bits of the f64, mm) and their models.
    others: Vec<(u64, ErrorModel)>,
}

impl<'m> ToolModels<'m> {
    /// Only the base model (the machine file's `[tool]`); others are added by [`ToolModels::prepare`].
    pub fn new(base: &'m ErrorModel) -> Self {
        ToolModels {
            base,
            others: Vec::new(),
        }
    }

    /// Make sure the models of these tools exist.
    pub fn prepare<'t>(&mut self, tools: impl IntoIterator<Item = &'t ToolInUse>) {
        for tool in tools {
            if self.find(tool).is_none() {
                let length = tool.length_mm;
                self.others
                    .push((length.to_bits(), self.base.with_tool_length(length)));
            }
        }
    }

    fn find(&self, tool: &ToolInUse) -> Option<&ErrorModel> {
        if tool.number == 0 || tool.length_mm == self.base.kinematics().tool_length {
            return Some(self.base);
        }
        let bits = tool.length_mm.to_bits();
        self.others.iter().find(|(b, _)| *b == bits).map(|(_, m)| m)
    }

    /// The model with `tool` in the spindle ([`Self::prepare`]d; otherwise the
    /// base model, which a debug build refuses).
    pub fn get(&self, tool: &ToolInUse) -> &ErrorModel {
        let found = self.find(tool);
        debug_assert!(found.is_some(), "tool {tool} was not prepared");
        found.unwrap_or(self.base)
    }

    /// The model with `tool`, made when it is new.
    pub fn get_or_make(&mut self, tool: &ToolInUse) -> &ErrorModel {
        self.prepare([tool]);
        self.get(tool)
    }

    /// The tool length the model of `tool` uses, mm.
    pub fn length_mm(&self, tool: &ToolInUse) -> f64 {
        self.get(tool).kinematics().tool_length
    }

    /// Lookups that held an end value, over every tool's model (they share
    /// the base model's count: [`ErrorModel::with_tool_length`]).
    pub fn held_lookups(&self) -> u64 {
        self.base.held_lookups()
    }

    /// Lookups held over the sliver beyond a table's end, over every tool's
    /// model ([`ErrorModel::holding_ends`]).
    pub fn table_end_lookups(&self) -> u64 {
        self.base.table_end_lookups()
            + self
                .others
                .iter()
                .map(|(_, m)| m.table_end_lookups())
                .sum::<u64>()
    }
}

/// The kinematics of `model` with `tool` in the spindle (tool 0: the model's own).
pub fn kinematics_with(model: &ErrorModel, tool: &ToolInUse) -> crate::kinematics::Kinematics {
    kinematics_for_tool(model.kinematics(), tool)
}

/// `kinematics` with `tool` in the spindle (tool 0: `kinematics` as it is).
pub fn kinematics_for_tool(
    kinematics: &crate::kinematics::Kinematics,
    tool: &ToolInUse,
) -> crate::kinematics::Kinematics {
    if tool.number == 0 {
        *kinematics
    } else {
        kinematics.with_tool_length(tool.length_mm)
    }
}
