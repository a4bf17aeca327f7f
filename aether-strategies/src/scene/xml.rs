//! Mitsuba XML into a tree of plugin declarations.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DVec3, Mat4, Vec3};

use crate::files::{MAX_SCENE_BYTES, check_regular, read_regular};

/// Where something was declared.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file.
    pub file: Arc<Path>,
    /// The 1-based line, or 0 for the file as a whole (one that cannot be
    /// read at all).
    pub line: u32,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            0 => write!(f, "{}", self.file.display()),
            line => write!(f, "{}:{line}", self.file.display()),
        }
    }
}

/// The deepest nesting of elements read: far deeper than any scene needs,
/// shallow enough that reading it cannot overflow the stack.
pub const MAX_NESTING: usize = 100;

/// A scene that could not be read: the file, the line, the element and why.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneError {
    /// Where.
    pub location: Location,
    /// The element, as written (`<float name="fov">`).
    pub element: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.element.is_empty() {
            write!(f, "{}: {}", self.location, self.message)
        } else {
            write!(f, "{}: {}: {}", self.location, self.element, self.message)
        }
    }
}

impl std::error::Error for SceneError {}

/// Something the reader skipped: an element it does not know.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    /// Where.
    pub location: Location,
    /// What.
    pub message: String,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: warning: {}", self.location, self.message)
    }
}

/// A spectrum as written; [`crate::scene`] converts it to linear sRGB.
#[derive(Clone, Debug, PartialEq)]
pub enum SpectrumValue {
    /// The same value at every wavelength.
    Constant(f64),
    /// Three values: linear RGB (Mitsuba's RGB mode reads them so).
    Rgb([f64; 3]),
    /// Values at wavelengths in nanometres, in increasing order.
    Sampled(Vec<(f64, f64)>),
}

/// A typed property value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `<float>`.
    Float(f64),
    /// `<integer>`.
    Integer(i64),
    /// `<boolean>`.
    Boolean(bool),
    /// `<string>`.
    String(String),
    /// `<spectrum>`.
    Spectrum(SpectrumValue),
    /// `<rgb>` or `<srgb>` (converted to linear).
    Rgb([f64; 3]),
    /// `<point>`.
    Point(Vec3),
    /// `<vector>`.
    Vector(Vec3),
    /// `<transform>`.
    Transform(Mat4),
}

impl Value {
    fn kind(&self) -> &'static str {
        match self {
            Value::Float(_) => "float",
            Value::Integer(_) => "integer",
            Value::Boolean(_) => "boolean",
            Value::String(_) => "string",
            Value::Spectrum(_) => "spectrum",
            Value::Rgb(_) => "rgb",
            Value::Point(_) => "point",
            Value::Vector(_) => "vector",
            Value::Transform(_) => "transform",
        }
    }
}

/// A named property with where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Property {
    /// Its name.
    pub name: String,
    /// Its value.
    pub value: Value,
    /// Where.
    pub location: Location,
}

/// The set of property names read from an object (thread-safe; equal and
/// cloned as sets, ignored by equality of objects).
#[derive(Debug, Default)]
pub struct ReadMarks(std::sync::Mutex<std::collections::HashSet<String>>);

impl Clone for ReadMarks {
    fn clone(&self) -> Self {
        ReadMarks(std::sync::Mutex::new(
            self.0.lock().map(|s| s.clone()).unwrap_or_default(),
        ))
    }
}

impl PartialEq for ReadMarks {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

impl ReadMarks {
    fn mark(&self, name: &str) {
        if let Ok(mut s) = self.0.lock() {
            s.insert(name.to_string());
        }
    }

    fn contains(&self, name: &str) -> bool {
        self.0.lock().is_ok_and(|s| s.contains(name))
    }
}

/// The kinds of plugin a scene declares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Category {
    /// `<scene>`.
    Scene,
    /// `<shape>`.
    Shape,
    /// `<bsdf>`.
    Bsdf,
    /// `<emitter>`.
    Emitter,
    /// `<sensor>`.
    Sensor,
    /// `<film>`.
    Film,
    /// `<rfilter>`.
    Rfilter,
    /// `<sampler>`.
    Sampler,
    /// `<integrator>`.
    Integrator,
    /// `<texture>`.
    Texture,
    /// `<medium>`.
    Medium,
    /// `<phase>`.
    Phase,
}

impl Category {
    fn from_tag(tag: &str) -> Option<Self> {
        Some(match tag {
            "scene" => Category::Scene,
            "shape" => Category::Shape,
            "bsdf" => Category::Bsdf,
            "emitter" => Category::Emitter,
            "sensor" => Category::Sensor,
            "film" => Category::Film,
            "rfilter" => Category::Rfilter,
            "sampler" => Category::Sampler,
            "integrator" => Category::Integrator,
            "texture" => Category::Texture,
            "medium" => Category::Medium,
            "phase" => Category::Phase,
            _ => return None,
        })
    }
}

/// A plugin declaration: `<shape type="obj" id="...">` with its properties
/// and nested plugins. References are resolved: a `<ref id>` appears as the
/// referenced object (shared through `Arc`).
#[derive(Clone, Debug, PartialEq)]
pub struct Object {
    /// The kind of plugin.
    pub category: Category,
    /// The `type` attribute.
    pub kind: String,
    /// The `id` attribute.
    pub id: Option<String>,
    /// The `name` attribute (for an object used as a named parameter).
    pub name: Option<String>,
    /// Properties in declaration order.
    pub properties: Vec<Property>,
    /// Nested and referenced objects in declaration order.
    pub children: Vec<Arc<Object>>,
    /// Where it was declared.
    pub location: Location,
    /// Names of the properties the loader has read, so that the others can
    /// be reported.
    pub read: ReadMarks,
}

impl Object {
    /// The element as written, for messages: `<bsdf type="diffuse" id="white">`.
    #[must_use]
    pub fn describe(&self) -> String {
        let tag = format!("{:?}", self.category).to_lowercase();
        let mut s = match self.kind.as_str() {
            "" => format!("<{tag}"),
            kind => format!("<{tag} type=\"{kind}\""),
        };
        if let Some(id) = &self.id {
            s += &format!(" id=\"{id}\"");
        }
        s + ">"
    }

    /// The property `name`, if set.
    #[must_use]
    pub fn property(&self, name: &str) -> Option<&Property> {
        self.read.mark(name);
        self.properties.iter().find(|p| p.name == name)
    }

    /// Warnings for the properties of this object and its nested objects
    /// that nothing read: a misspelt or unsupported parameter.
    #[must_use]
    pub fn unread(&self) -> Vec<Warning> {
        let mut out: Vec<Warning> = self
            .properties
            .iter()
            .filter(|p| !self.read.contains(&p.name))
            .map(|p| Warning {
                location: p.location.clone(),
                message: format!(
                    "the property '{}' of {} is not used",
                    p.name,
                    self.describe()
                ),
            })
            .collect();
        for c in &self.children {
            out.extend(c.unread());
        }
        out
    }

    /// Nested objects of a category.
    pub fn children_of(&self, category: Category) -> impl Iterator<Item = &Arc<Object>> {
        self.children.iter().filter(move |c| c.category == category)
    }

    /// An error about this object.
    #[must_use]
    pub fn error(&self, message: impl Into<String>) -> SceneError {
        SceneError {
            location: self.location.clone(),
            element: self.describe(),
            message: message.into(),
        }
    }

    fn typed<T>(
        &self,
        name: &str,
        get: impl Fn(&Value) -> Option<T>,
        wanted: &str,
    ) -> Result<Option<T>, SceneError> {
        match self.property(name) {
            None => Ok(None),
            Some(p) => get(&p.value).map(Some).ok_or_else(|| SceneError {
                location: p.location.clone(),
                element: format!("<{} name=\"{name}\">", p.value.kind()),
                message: format!("{} expects {wanted} for '{name}'", self.describe()),
            }),
        }
    }

    /// A float property (integers are accepted), or `default`.
    pub fn float(&self, name: &str, default: f64) -> Result<f64, SceneError> {
        let get = |v: &Value| match v {
            Value::Float(x) => Some(*x),
            Value::Integer(i) => Some(*i as f64),
            _ => None,
        };
        Ok(self.typed(name, get, "a float")?.unwrap_or(default))
    }

    /// An integer property, or `default`.
    pub fn integer(&self, name: &str, default: i64) -> Result<i64, SceneError> {
        Ok(self
            .typed(
                name,
                |v| {
                    if let Value::Integer(i) = v {
                        Some(*i)
                    } else {
                        None
                    }
                },
                "an integer",
            )?
            .unwrap_or(default))
    }

    /// A boolean property, or `default`.
    pub fn boolean(&self, name: &str, default: bool) -> Result<bool, SceneError> {
        Ok(self
            .typed(
                name,
                |v| {
                    if let Value::Boolean(b) = v {
                        Some(*b)
                    } else {
                        None
                    }
                },
                "a boolean",
            )?
            .unwrap_or(default))
    }

    /// A string property.
    pub fn string(&self, name: &str) -> Result<Option<&str>, SceneError> {
        match self.property(name) {
            Some(Property {
                value: Value::String(s),
                ..
            }) => Ok(Some(s)),
            Some(_) => self.typed(name, |_| None::<&str>, "a string"),
            None => Ok(None),
        }
    }

    /// A transform property, or the identity.
    pub fn transform(&self, name: &str) -> Result<Mat4, SceneError> {
        Ok(self
            .typed(
                name,
                |v| {
                    if let Value::Transform(m) = v {
                        Some(*m)
                    } else {
                        None
                    }
                },
                "a transform",
            )?
            .unwrap_or(Mat4::IDENTITY))
    }

    /// A point property, or `default`.
    pub fn point(&self, name: &str, default: Vec3) -> Result<Vec3, SceneError> {
        Ok(self
            .typed(
                name,
                |v| {
                    if let Value::Point(p) | Value::Vector(p) = v {
                        Some(*p)
                    } else {
                        None
                    }
                },
                "a point",
            )?
            .unwrap_or(default))
    }
}

/// A parsed scene: the root `<scene>` object, and what was skipped.
#[derive(Clone, Debug)]
pub struct SceneFile {
    /// The root object.
    pub root: Arc<Object>,
    /// Elements that were skipped, with their location.
    pub warnings: Vec<Warning>,
}

/// Reads a Mitsuba scene file. `params` override the file's `<default>`s
/// (as Mitsuba's `-D name=value`).
pub fn read_scene(path: &Path, params: &HashMap<String, String>) -> Result<SceneFile, SceneError> {
    let mut reader = Reader {
        params: params.clone(),
        ids: HashMap::new(),
        warnings: Vec::new(),
        include_stack: Vec::new(),
        depth: 0,
    };
    let root = reader.file(path)?;
    Ok(SceneFile {
        root: Arc::new(root),
        warnings: reader.warnings,
    })
}

/// Reads a scene from a string, as if it were the file `path` (relative
/// paths inside resolve against its folder).
pub fn read_scene_str(
    text: &str,
    path: &Path,
    params: &HashMap<String, String>,
) -> Result<SceneFile, SceneError> {
    let mut reader = Reader {
        params: params.clone(),
        ids: HashMap::new(),
        warnings: Vec::new(),
        include_stack: Vec::new(),
        depth: 0,
    };
    let root = reader.text(text, path)?;
    Ok(SceneFile {
        root: Arc::new(root),
        warnings: reader.warnings,
    })
}

struct Reader {
    params: HashMap<String, String>,
    ids: HashMap<String, Arc<Object>>,
    warnings: Vec<Warning>,
    include_stack: Vec<PathBuf>,
    /// Objects open around the one being read.
    depth: usize,
}

/// Context for errors inside one file.
struct Context<'a> {
    file: Arc<Path>,
    doc: &'a roxmltree::Document<'a>,
}

impl Context<'_> {
    fn location(&self, node: roxmltree::Node<'_, '_>) -> Location {
        Location {
            file: self.file.clone(),
            line: self.doc.text_pos_at(node.range().start).row,
        }
    }

    fn error(&self, node: roxmltree::Node<'_, '_>, message: impl Into<String>) -> SceneError {
        SceneError {
            location: self.location(node),
            element: describe(node),
            message: message.into(),
        }
    }
}

fn describe(node: roxmltree::Node<'_, '_>) -> String {
    let mut s = format!("<{}", node.tag_name().name());
    for key in ["type", "name", "id"] {
        if let Some(v) = node.attribute(key) {
            s += &format!(" {key}=\"{v}\"");
        }
    }
    s + ">"
}

impl Reader {
    fn file(&mut self, path: &Path) -> Result<Object, SceneError> {
        let at = |line: u32, message: String| SceneError {
            location: Location {
                file: Arc::from(path),
                line,
            },
            element: String::new(),
            message,
        };
        let bytes = read_regular(path, MAX_SCENE_BYTES)
            .map_err(|e| at(0, format!("cannot read the scene file: {e}")))?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let offset = e.utf8_error().valid_up_to();
            let before = &e.as_bytes()[..offset];
            let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
            let column = offset
                - before
                    .iter()
                    .rposition(|&b| b == b'\n')
                    .map_or(0, |i| i + 1)
                + 1;
            at(
                u32::try_from(line).unwrap_or(u32::MAX),
                format!(
                    "invalid UTF-8 at byte {offset} (column {column}): a scene file is UTF-8 text"
                ),
            )
        })?;
        self.text(&text, path)
    }

    fn text(&mut self, text: &str, path: &Path) -> Result<Object, SceneError> {
        let file: Arc<Path> = Arc::from(path);
        let doc = roxmltree::Document::parse(text).map_err(|e| {
            // The parser places an early end at the start: it is at the end.
            let (line, message) = match e {
                roxmltree::Error::UnexpectedEndOfStream => (
                    text.lines().count().max(1) as u32,
                    "the file ends inside an element: it is truncated or an element is not closed"
                        .to_string(),
                ),
                e => (e.pos().row, format!("malformed XML: {e}")),
            };
            SceneError {
                location: Location {
                    file: file.clone(),
                    line,
                },
                element: String::new(),
                message,
            }
        })?;
        let cx = Context { file, doc: &doc };
        let root = doc.root_element();
        if root.tag_name().name() != "scene" {
            return Err(cx.error(root, "the root element must be <scene>"));
        }
        // Defaults first: they apply to the whole file, wherever written.
        for node in root.children().filter(|n| n.has_tag_name("default")) {
            let (name, value) = (
                self.required(&cx, node, "name")?,
                self.required(&cx, node, "value")?,
            );
            self.params
                .entry(name.to_string())
                .or_insert_with(|| value.to_string());
        }
        let mut scene = Object {
            category: Category::Scene,
            kind: String::new(),
            id: None,
            name: None,
            properties: Vec::new(),
            children: Vec::new(),
            location: cx.location(root),
            read: ReadMarks::default(),
        };
        self.body(&cx, root, &mut scene)?;
        Ok(scene)
    }

    fn required<'n>(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'n, '_>,
        attr: &str,
    ) -> Result<&'n str, SceneError> {
        node.attribute(attr)
            .ok_or_else(|| cx.error(node, format!("the '{attr}' attribute is missing")))
    }

    /// An attribute with `$param`s substituted.
    fn attr(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        attr: &str,
    ) -> Result<Option<String>, SceneError> {
        let Some(raw) = node.attribute(attr) else {
            return Ok(None);
        };
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out += &rest[..i];
            let after = &rest[i + 1..];
            let end = after
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(after.len());
            let name = &after[..end];
            let value = self.params.get(name).ok_or_else(|| cx.error(node, format!("'${name}' has no value: declare <default name=\"{name}\" value=\"...\"/> or pass it on the command line")))?;
            out += value;
            rest = &after[end..];
        }
        out += rest;
        Ok(Some(out))
    }

    fn body(
        &mut self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        object: &mut Object,
    ) -> Result<(), SceneError> {
        for child in node.children().filter(roxmltree::Node::is_element) {
            let tag = child.tag_name().name();
            if let Some(category) = Category::from_tag(tag) {
                if category == Category::Scene {
                    return Err(cx.error(child, "a <scene> cannot be nested"));
                }
                let obj = Arc::new(self.object(cx, child, category)?);
                if let Some(id) = &obj.id {
                    if self.ids.insert(id.clone(), obj.clone()).is_some() {
                        return Err(cx.error(child, format!("the id '{id}' is declared twice")));
                    }
                }
                object.children.push(obj);
                continue;
            }
            match tag {
                "default" => {}
                "ref" => {
                    let id = self
                        .attr(cx, child, "id")?
                        .ok_or_else(|| cx.error(child, "the 'id' attribute is missing"))?;
                    let target = self.ids.get(&id).ok_or_else(|| {
                        cx.error(
                            child,
                            format!("no object with id '{id}' is declared before this reference"),
                        )
                    })?;
                    let mut target = target.clone();
                    if let Some(name) = self.attr(cx, child, "name")? {
                        Arc::make_mut(&mut target).name = Some(name);
                    }
                    object.children.push(target);
                }
                "include" => {
                    let name = self
                        .attr(cx, child, "filename")?
                        .ok_or_else(|| cx.error(child, "the 'filename' attribute is missing"))?;
                    let path = cx.file.parent().unwrap_or(Path::new(".")).join(&name);
                    if self.include_stack.contains(&path) {
                        return Err(cx.error(child, format!("{} includes itself", path.display())));
                    }
                    check_regular(&path, MAX_SCENE_BYTES)
                        .map_err(|e| cx.error(child, format!("the included file: {e}")))?;
                    self.include_stack.push(path.clone());
                    let included = self.file(&path);
                    self.include_stack.pop();
                    let included = included?;
                    object.children.extend(included.children);
                    object.properties.extend(included.properties);
                }
                "float" | "integer" | "boolean" | "string" | "spectrum" | "rgb" | "srgb"
                | "point" | "vector" | "transform" | "blackbody" => {
                    let name = self
                        .attr(cx, child, "name")?
                        .ok_or_else(|| cx.error(child, "the 'name' attribute is missing"))?;
                    let value = self.value(cx, child, tag)?;
                    let property = Property {
                        name,
                        value,
                        location: cx.location(child),
                    };
                    // Mitsuba keeps the last value of a property set twice;
                    // a shipped scene (door-bdpt.xml) relies on it.
                    if let Some(earlier) = object
                        .properties
                        .iter_mut()
                        .find(|p| p.name == property.name)
                    {
                        self.warnings.push(Warning {
                            location: property.location.clone(),
                            message: format!("the property '{}' is set again (first at line {}); the later value is used", property.name, earlier.location.line),
                        });
                        *earlier = property;
                    } else {
                        object.properties.push(property);
                    }
                }
                other => self.warnings.push(Warning {
                    location: cx.location(child),
                    message: format!("unknown element <{other}> is ignored"),
                }),
            }
        }
        Ok(())
    }

    fn object(
        &mut self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        category: Category,
    ) -> Result<Object, SceneError> {
        let kind = self
            .attr(cx, node, "type")?
            .ok_or_else(|| cx.error(node, "the 'type' attribute is missing"))?;
        let mut object = Object {
            category,
            kind,
            id: self.attr(cx, node, "id")?,
            name: self.attr(cx, node, "name")?,
            properties: Vec::new(),
            children: Vec::new(),
            location: cx.location(node),
            read: ReadMarks::default(),
        };
        if self.depth >= MAX_NESTING {
            return Err(cx.error(
                node,
                format!("objects are nested more than {MAX_NESTING} deep"),
            ));
        }
        self.depth += 1;
        let body = self.body(cx, node, &mut object);
        self.depth -= 1;
        body?;
        Ok(object)
    }

    fn numbers(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        text: &str,
    ) -> Result<Vec<f64>, SceneError> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .map(|s| {
                let x: f64 = s
                    .parse()
                    .map_err(|_| cx.error(node, format!("'{s}' is not a number")))?;
                if x.is_finite() {
                    Ok(x)
                } else {
                    Err(cx.error(node, format!("'{s}' is not a finite number")))
                }
            })
            .collect()
    }

    fn number(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        attr: &str,
    ) -> Result<Option<f64>, SceneError> {
        match self.attr(cx, node, attr)? {
            None => Ok(None),
            Some(text) => match self.numbers(cx, node, &text)?.as_slice() {
                [x] => Ok(Some(*x)),
                _ => Err(cx.error(node, format!("'{attr}' must be one number, not '{text}'"))),
            },
        }
    }

    fn value(
        &mut self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        tag: &str,
    ) -> Result<Value, SceneError> {
        let text = || {
            self.attr(cx, node, "value")?
                .ok_or_else(|| cx.error(node, "the 'value' attribute is missing"))
        };
        Ok(match tag {
            "float" => Value::Float(
                self.number(cx, node, "value")?
                    .ok_or_else(|| cx.error(node, "the 'value' attribute is missing"))?,
            ),
            "integer" => {
                let t = text()?;
                Value::Integer(
                    t.trim()
                        .parse()
                        .map_err(|_| cx.error(node, format!("'{t}' is not an integer")))?,
                )
            }
            "boolean" => match text()?.trim() {
                "true" => Value::Boolean(true),
                "false" => Value::Boolean(false),
                other => return Err(cx.error(node, format!("'{other}' is not 'true' or 'false'"))),
            },
            "string" => Value::String(text()?),
            "spectrum" => Value::Spectrum(self.spectrum(cx, node, &text()?)?),
            "rgb" | "srgb" => {
                let v = self.numbers(cx, node, &text()?)?;
                let rgb = match v.as_slice() {
                    [x] => [*x; 3],
                    [r, g, b] => [*r, *g, *b],
                    _ => return Err(cx.error(node, "an RGB value needs one or three numbers")),
                };
                Value::Rgb(if tag == "srgb" {
                    rgb.map(srgb_to_linear)
                } else {
                    rgb
                })
            }
            "point" | "vector" => {
                let p = match self.attr(cx, node, "value")? {
                    Some(t) => match self.numbers(cx, node, &t)?.as_slice() {
                        [x, y, z] => Vec3::new(*x as f32, *y as f32, *z as f32),
                        _ => return Err(cx.error(node, "a point needs three numbers")),
                    },
                    None => {
                        let c = |a| {
                            Ok::<f32, SceneError>(self.number(cx, node, a)?.unwrap_or(0.0) as f32)
                        };
                        Vec3::new(c("x")?, c("y")?, c("z")?)
                    }
                };
                if tag == "point" {
                    Value::Point(p)
                } else {
                    Value::Vector(p)
                }
            }
            "transform" => Value::Transform(self.transform(cx, node)?),
            _ => {
                return Err(cx.error(
                    node,
                    format!("<{tag}> is not supported: it would change the image"),
                ));
            }
        })
    }

    fn spectrum(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
        text: &str,
    ) -> Result<SpectrumValue, SceneError> {
        if text.contains(':') {
            let mut samples = Vec::new();
            for pair in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                let (l, v) = pair.split_once(':').ok_or_else(|| {
                    cx.error(node, format!("'{pair}' is not a wavelength:value pair"))
                })?;
                let n = self.numbers(cx, node, &format!("{l} {v}"))?;
                samples.push((n[0], n[1]));
            }
            if samples.windows(2).any(|w| w[1].0 <= w[0].0) {
                return Err(cx.error(node, "wavelengths must increase"));
            }
            return Ok(SpectrumValue::Sampled(samples));
        }
        match self.numbers(cx, node, text)?.as_slice() {
            [x] => Ok(SpectrumValue::Constant(*x)),
            [r, g, b] => Ok(SpectrumValue::Rgb([*r, *g, *b])),
            v => Err(cx.error(
                node,
                format!(
                    "a spectrum needs one value, three (RGB) or wavelength:value pairs, not {}",
                    v.len()
                ),
            )),
        }
    }

    /// A `<transform>`: its operations applied in order, each after the last.
    fn transform(
        &self,
        cx: &Context<'_>,
        node: roxmltree::Node<'_, '_>,
    ) -> Result<Mat4, SceneError> {
        let mut m = DMat4::IDENTITY;
        for op in node.children().filter(roxmltree::Node::is_element) {
            let v3 = |default: f64| -> Result<DVec3, SceneError> {
                if let Some(t) = self.attr(cx, op, "value")? {
                    return match self.numbers(cx, op, &t)?.as_slice() {
                        [x] => Ok(DVec3::splat(*x)),
                        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                        _ => Err(cx.error(op, "needs one or three numbers")),
                    };
                }
                let c = |a| Ok::<f64, SceneError>(self.number(cx, op, a)?.unwrap_or(default));
                Ok(DVec3::new(c("x")?, c("y")?, c("z")?))
            };
            let step = match op.tag_name().name() {
                "translate" => DMat4::from_translation(v3(0.0)?),
                "scale" => DMat4::from_scale(v3(1.0)?),
                "rotate" => {
                    let axis = v3(0.0)?;
                    let angle = self
                        .number(cx, op, "angle")?
                        .ok_or_else(|| cx.error(op, "the 'angle' attribute is missing"))?;
                    let axis = axis
                        .try_normalize()
                        .ok_or_else(|| cx.error(op, "the rotation axis is zero"))?;
                    DMat4::from_axis_angle(axis, angle.to_radians())
                }
                "matrix" => {
                    let t = self
                        .attr(cx, op, "value")?
                        .ok_or_else(|| cx.error(op, "the 'value' attribute is missing"))?;
                    let v = self.numbers(cx, op, &t)?;
                    match v.len() {
                        16 => DMat4::from_cols_array(&[
                            v[0], v[4], v[8], v[12], v[1], v[5], v[9], v[13], v[2], v[6], v[10],
                            v[14], v[3], v[7], v[11], v[15],
                        ]),
                        9 => DMat4::from_cols_array(&[
                            v[0], v[3], v[6], 0.0, v[1], v[4], v[7], 0.0, v[2], v[5], v[8], 0.0,
                            0.0, 0.0, 0.0, 1.0,
                        ]),
                        n => {
                            return Err(
                                cx.error(op, format!("a matrix needs 16 or 9 numbers, not {n}"))
                            );
                        }
                    }
                }
                "lookat" => {
                    let p = |a: &str| -> Result<DVec3, SceneError> {
                        let t = self.attr(cx, op, a)?.ok_or_else(|| {
                            cx.error(op, format!("the '{a}' attribute is missing"))
                        })?;
                        match self.numbers(cx, op, &t)?.as_slice() {
                            [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
                            _ => Err(cx.error(op, format!("'{a}' needs three numbers"))),
                        }
                    };
                    let (origin, target) = (p("origin")?, p("target")?);
                    let up = if op.attribute("up").is_some() {
                        p("up")?
                    } else {
                        DVec3::Y
                    };
                    look_at(origin, target, up).ok_or_else(|| {
                        cx.error(op, "origin, target and up do not define a frame")
                    })?
                }
                other => {
                    return Err(cx.error(op, format!("<{other}> is not a transform operation")));
                }
            };
            m = step * m;
        }
        // Geometry is transformed in single precision, and normals by the
        // inverse: both must exist there (a scale of 1e-40 is not zero in
        // f64, but its inverse is infinite in f32).
        let single = m.as_mat4();
        if !single.is_finite() || m.determinant() == 0.0 || !m.inverse().as_mat4().is_finite() {
            return Err(cx.error(
                node,
                "the transform is singular or not finite (in single precision)",
            ));
        }
        Ok(single)
    }
}

/// Mitsuba's look-at transform: local +z towards the target, +y up, x to
/// the left; `None` if the three points do not define a frame.
#[must_use]
pub fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    ))
}

fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}
